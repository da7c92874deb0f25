// simgate/core/suggest.h — "did you mean ...?" for names a user typed.
//
// closest_match() finds the candidate nearest to a misspelt word (edit distance with
// transpositions, case-insensitive), if one is near enough to be a likely typo: at most a
// third of the word's length, and at least one edit. Used for unknown configuration keys,
// type names, components and services. Pure functions; any thread.
#ifndef SIMGATE_CORE_SUGGEST_H_
#define SIMGATE_CORE_SUGGEST_H_

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace simgate {

// Optimal string alignment distance between a and b (insertions, deletions, substitutions
// and transpositions of neighbours each count one), ignoring ASCII case.
std::size_t edit_distance(std::string_view a, std::string_view b);

// The candidate nearest to `word` when it is a likely misspelling of it; ties go to the
// first candidate. An exact match is not a suggestion (nullopt).
std::optional<std::string> closest_match(std::string_view word,
                                         const std::vector<std::string>& candidates);

// " (did you mean 'x'?)" or "".
std::string did_you_mean(std::string_view word, const std::vector<std::string>& candidates);

}  // namespace simgate

#endif  // SIMGATE_CORE_SUGGEST_H_
