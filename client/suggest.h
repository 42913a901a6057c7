// "Did you mean ...": the known word nearest a mistyped subcommand or flag.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace cellflow::client {

// Levenshtein distance (insertions, deletions, substitutions; a swap of two
// neighbouring characters counts 1, as in Damerau's optimal string alignment).
std::size_t edit_distance(const std::string& a, const std::string& b);

// The candidate nearest `word`, or "" when none is close enough: at most
// max(1, length / 3) edits away (leading dashes not counted in the length), or
// `word` a prefix of exactly one candidate.
std::string closest_word(const std::string& word, const std::vector<std::string>& candidates);

}  // namespace cellflow::client
