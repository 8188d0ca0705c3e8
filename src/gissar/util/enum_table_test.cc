#include "gissar/util/enum_table.h"

#include <gtest/gtest.h>

namespace gissar::util {
namespace {

enum class Fruit { kApple, kPear, kQuince };
constexpr auto kFruits =
    MakeEnumTable<Fruit>("fruit", {{Fruit::kApple, "apple"}, {Fruit::kPear, "pear"}, {Fruit::kQuince, "quince"}},
                         {{Fruit::kPear, "poire"}, {Fruit::kApple, ""}});

enum class Channel { kHH, kVV };
constexpr auto kChannels =
    MakeEnumTable<Channel>("channel", {{Channel::kHH, "HH"}, {Channel::kVV, "VV"}}, EnumCase::kInsensitive);

enum class Only { kOne };
constexpr auto kOnly = MakeEnumTable<Only>("only value", {{Only::kOne, "one"}});

// Built at compile time, so usable in constant expressions.
static_assert(kFruits.Find("quince") == Fruit::kQuince);
static_assert(!kFruits.Find("plum").has_value());
static_assert(kFruits.Entries().size() == 3 && kFruits.Aliases().size() == 2);

TEST(EnumTableTest, RoundTripsEveryEntry) {
  for (const auto& entry : kFruits.Entries()) {
    EXPECT_EQ(kFruits.Parse(kFruits.Name(entry.value), "--fruit"), entry.value);
  }
  for (const auto& entry : kChannels.Entries()) {
    EXPECT_EQ(kChannels.Parse(kChannels.Name(entry.value), "--channel"), entry.value);
  }
  EXPECT_EQ(kFruits.Name(Fruit::kApple), "apple");
  EXPECT_EQ(kFruits.Name(Fruit::kPear), "pear");
  EXPECT_EQ(kFruits.Name(Fruit::kQuince), "quince");
}

TEST(EnumTableTest, ListsTheCanonicalNamesInTableOrder) {
  EXPECT_EQ(kFruits.Names(), (std::vector<std::string>{"apple", "pear", "quince"}));
  EXPECT_EQ(kFruits.List(), "apple, pear, quince");
  EXPECT_EQ(kFruits.List("|"), "apple|pear|quince");
  EXPECT_EQ(kFruits.Alternatives(), "apple, pear or quince");
  EXPECT_EQ(kChannels.Alternatives(), "HH or VV");
  EXPECT_EQ(kOnly.Alternatives(), "one");
  EXPECT_EQ(kOnly.List(), "one");
}

TEST(EnumTableTest, AcceptsAliasesButNeverPrintsThem) {
  EXPECT_EQ(kFruits.Parse("poire", "--fruit"), Fruit::kPear);
  EXPECT_EQ(kFruits.Parse("", "--fruit"), Fruit::kApple);
  EXPECT_EQ(kFruits.Name(Fruit::kPear), "pear");
  EXPECT_EQ(kFruits.List().find("poire"), std::string::npos);
}

TEST(EnumTableTest, MatchesExactlyUnlessCaseInsensitive) {
  EXPECT_THROW(kFruits.Parse("Apple", "--fruit"), ConfigError);
  EXPECT_THROW(kFruits.Parse("apple ", "--fruit"), ConfigError);
  EXPECT_EQ(kChannels.Parse("hh", "--channel"), Channel::kHH);
  EXPECT_EQ(kChannels.Parse("vV", "--channel"), Channel::kVV);
  EXPECT_EQ(kChannels.Name(Channel::kVV), "VV");
  EXPECT_THROW(kChannels.Parse("HHH", "--channel"), ConfigError);
}

TEST(EnumTableTest, ErrorNamesTheTextTheOptionAndEveryChoice) {
  try {
    kFruits.Parse("plum", "--fruit");
    FAIL() << "an unknown name was accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.message(), "unknown fruit 'plum': must be apple, pear or quince");
    EXPECT_EQ(e.where(), "--fruit");
    const std::string what = e.what();
    EXPECT_NE(what.find("--fruit"), std::string::npos) << what;
    EXPECT_NE(what.find("'plum'"), std::string::npos) << what;
    for (const std::string& name : kFruits.Names()) EXPECT_NE(what.find(name), std::string::npos) << name;
    EXPECT_EQ(what.find("poire"), std::string::npos) << what;
  }
}

TEST(EnumTableTest, ThrowsTheErrorTypeAsked) {
  try {
    kFruits.Parse<InputError>("plum", "fruits.csv row 3");
    FAIL() << "an unknown name was accepted";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "unknown fruit 'plum': must be apple, pear or quince (fruits.csv row 3)");
  }
  EXPECT_EQ(kOnly.UnknownMessage("two"), "unknown only value 'two': must be one");
}

}  // namespace
}  // namespace gissar::util
