#include "gissar/util/utc_time.h"

#include <cmath>
#include <cstdio>

#include "gissar/util/error.h"

namespace gissar {

int64_t DaysFromCivil(int64_t year, unsigned month, unsigned day) {
  // H. Hinnant's days_from_civil: years start in March so that the leap day
  // is the last day of the (shifted) year.
  year -= month <= 2;
  const int64_t era = (year >= 0 ? year : year - 399) / 400;
  const unsigned year_of_era = static_cast<unsigned>(year - era * 400);
  const unsigned day_of_year = (153 * (month + (month > 2 ? -3 : 9)) + 2) / 5 + day - 1;
  const unsigned day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
  return era * 146097 + static_cast<int64_t>(day_of_era) - 719468;
}

namespace {

// The inverse of DaysFromCivil (Hinnant's civil_from_days).
void CivilFromDays(int64_t days, int* year, unsigned* month, unsigned* day) {
  days += 719468;
  const int64_t era = (days >= 0 ? days : days - 146096) / 146097;
  const unsigned day_of_era = static_cast<unsigned>(days - era * 146097);
  const unsigned year_of_era = (day_of_era - day_of_era / 1460 + day_of_era / 36524 - day_of_era / 146096) / 365;
  const unsigned day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
  const unsigned mp = (5 * day_of_year + 2) / 153;
  *day = day_of_year - (153 * mp + 2) / 5 + 1;
  *month = mp < 10 ? mp + 3 : mp - 9;
  *year = static_cast<int>(static_cast<int64_t>(year_of_era) + era * 400 + (*month <= 2));
}

bool IsLeap(int year) { return (year % 4 == 0 && year % 100 != 0) || year % 400 == 0; }

unsigned DaysInMonth(int year, unsigned month) {
  static constexpr unsigned kDays[] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  return month == 2 && IsLeap(year) ? 29 : kDays[month - 1];
}

}  // namespace

double ParseUtcSeconds(const std::string& text, const std::string& where) {
  std::string body = text;
  while (!body.empty() && (body.back() == ' ' || body.back() == '\n' || body.back() == '\r')) body.pop_back();
  size_t start = 0;
  while (start < body.size() && body[start] == ' ') ++start;
  body = body.substr(start);
  if (body.rfind("UTC=", 0) == 0) body = body.substr(4);
  if (!body.empty() && body.back() == 'Z') body.pop_back();
  if (body.size() > 10 && (body[10] == 'T' || body[10] == ' ')) body[10] = ' ';
  int year = 0, month = 0, day = 0, hour = 0, minute = 0, consumed = 0;
  double second = 0.0;
  const bool parsed = std::sscanf(body.c_str(), "%4d-%2d-%2d %2d:%2d:%lf%n", &year, &month, &day, &hour, &minute,
                                  &second, &consumed) == 6 &&
                      consumed == static_cast<int>(body.size());
  if (!parsed || month < 1 || month > 12 || day < 1 || unsigned(day) > DaysInMonth(year, unsigned(month)) ||
      hour < 0 || hour > 23 || minute < 0 || minute > 59 || !(second >= 0.0) || second >= 61.0) {
    throw InputError("'" + text + "' is not a UTC timestamp YYYY-MM-DDThh:mm:ss[.f][Z]", where);
  }
  return double(DaysFromCivil(year, unsigned(month), unsigned(day))) * 86400.0 + hour * 3600.0 + minute * 60.0 +
         second;
}

std::string FormatUtc(double unix_seconds) {
  const int64_t micro_total = std::llround(unix_seconds * 1e6);
  int64_t days = micro_total / (int64_t{86400} * 1000000);
  int64_t micro_of_day = micro_total - days * int64_t{86400} * 1000000;
  if (micro_of_day < 0) {
    micro_of_day += int64_t{86400} * 1000000;
    --days;
  }
  int year = 0;
  unsigned month = 0, day = 0;
  CivilFromDays(days, &year, &month, &day);
  const int64_t seconds_of_day = micro_of_day / 1000000;
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%04d-%02u-%02uT%02d:%02d:%02d.%06dZ", year, month, day,
                int(seconds_of_day / 3600), int(seconds_of_day / 60 % 60), int(seconds_of_day % 60),
                int(micro_of_day % 1000000));
  return buffer;
}

}  // namespace gissar
