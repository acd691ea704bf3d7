// The command a mistyped one was probably meant to be ("runn" -> "run"), for the command line's
// message: CLI11 only says that a subcommand is required.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace occmap {

// The name nearest to `typed` within 2 edits (or of which `typed` is a prefix of 2 or more
// characters, "cal" -> "calibrate"); empty when none is that near or two tie.
std::string NearestName(std::string_view typed, const std::vector<std::string>& names);

}  // namespace occmap
