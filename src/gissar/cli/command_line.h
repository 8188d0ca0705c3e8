// Rewriting a command line before CLI11 parses it: deprecated flag
// spellings (docs/conventions.md), --options FILE.json expanded into flags,
// and a "did you mean" suggestion for a misspelt flag or command.
#pragma once

#include <string>
#include <vector>

#include <CLI/CLI.hpp>

namespace gissar::cli {

// The one wording of a deprecation warning: "OLD is deprecated and will be
// removed; use REPLACEMENT".
std::string DeprecationWarning(const std::string& old_flag, const std::string& replacement);

// argv with deprecated spellings replaced (also in "--old=value" form); one
// warning per replaced flag naming the new one is appended to `warnings`.
std::vector<std::string> ReplaceDeprecatedFlags(int argc, const char* const* argv,
                                                std::vector<std::string>& warnings);

// Options-file keys whose flag is not FlagOfField(key) (a field that kept an
// older flag: evaluate's speckle_looks is --looks): RequestFlags registers
// them per command when it declares the flag; ExpandOptionsFile reads them.
// ClearOptionKeyFlags forgets every command's (RunCli, before declaring).
void RegisterOptionKeyFlag(const CLI::App* command, const std::string& key, const std::string& flag);
void ClearOptionKeyFlags();

// --options FILE.json: its keys (request field names) become flags placed
// before the command line's own, which win. Unknown key = ConfigError naming
// the key and the file. Booleans: true gives the flag, false omits it;
// null keeps the default; lists become "A,B".
void ExpandOptionsFile(CLI::App& app, std::vector<std::string>& args);

// Throws ConfigError "unknown command 'X'; did you mean Y?" when a command
// word of `args` names no command (even with --help, which would otherwise
// print the general help and succeed).
void CheckCommandWords(CLI::App& app, const std::vector<std::string>& args);

// "; did you mean X?" for the first unexpected word of `args` close to a
// flag or command name (at most 2 edits); "" when nothing is close.
std::string DidYouMean(CLI::App& app, const std::vector<std::string>& args);

}  // namespace gissar::cli
