#include "client/suggest.h"

#include <algorithm>
#include <limits>

namespace cellflow::client {

std::size_t edit_distance(const std::string& a, const std::string& b) {
  const std::size_t n = a.size(), m = b.size();
  std::vector<std::vector<std::size_t>> d(n + 1, std::vector<std::size_t>(m + 1));
  for (std::size_t i = 0; i <= n; ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= m; ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= n; ++i) {
    for (std::size_t j = 1; j <= m; ++j) {
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  }
  return d[n][m];
}

std::string closest_word(const std::string& word, const std::vector<std::string>& candidates) {
  const std::size_t dashes = std::min(word.find_first_not_of('-'), word.size());
  const std::size_t limit = std::max<std::size_t>(1, (word.size() - dashes) / 3);
  std::string best;
  std::size_t best_distance = std::numeric_limits<std::size_t>::max();
  std::vector<std::string> prefixed;
  for (const std::string& candidate : candidates) {
    const std::size_t distance = edit_distance(word, candidate);
    if (distance < best_distance) {
      best_distance = distance;
      best = candidate;
    }
    if (word.size() > dashes + 1 && candidate.size() > word.size() &&
        candidate.compare(0, word.size(), word) == 0)
      prefixed.push_back(candidate);
  }
  if (best_distance > 0 && best_distance <= limit) return best;
  if (prefixed.size() == 1) return prefixed.front();
  return "";
}

}  // namespace cellflow::client
