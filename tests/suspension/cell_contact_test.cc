// Contact repulsion: the force is minus the gradient of the energy (finite
// differences), the pair law, and the cell-list search finds exactly the
// pairs a brute-force search finds, across the periodic boundaries.
#include "physics/scenes/suspension/cell_contact.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>
#include <utility>
#include <vector>

namespace cellflow::contact_repulsion {
namespace {

TEST(Repulsion, PairLaw) {
  EXPECT_DOUBLE_EQ(repulsion_force(0.0, 1.5, 2.0), 2.0);  // F0 at zero gap
  EXPECT_DOUBLE_EQ(repulsion_force(1.5, 1.5, 2.0), 0.0);
  EXPECT_DOUBLE_EQ(repulsion_force(0.75, 1.5, 2.0), 0.5);  // F0 (1/2)^2
  EXPECT_DOUBLE_EQ(repulsion_energy(2.0, 1.5, 2.0), 0.0);
  // F = -dE/dd by central differences.
  for (double d : {0.1, 0.5, 1.0, 1.4}) {
    const double h = 1e-6;
    const double fd = -(repulsion_energy(d + h, 1.5, 2.0) - repulsion_energy(d - h, 1.5, 2.0)) / (2 * h);
    EXPECT_NEAR(fd, repulsion_force(d, 1.5, 2.0), 1e-8) << d;
  }
}

struct Cloud {
  std::vector<std::vector<double>> x, f;
  std::vector<std::vector<int>> surface;
};

// Random vertices of `cells` cells in a 10 x 12 x 8 box, some near the walls
// and across the periodic faces.
Cloud random_cloud(int cells, int per_cell, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  auto uniform = [&] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  Cloud c;
  for (int k = 0; k < cells; ++k) {
    c.x.emplace_back();
    c.f.emplace_back(3 * per_cell, 0.0);
    c.surface.emplace_back();
    for (int v = 0; v < per_cell; ++v) {
      c.x.back().push_back(-2.0 + 14.0 * uniform());  // unwrapped, beyond the box
      c.x.back().push_back(1.5 + 9.0 * uniform());
      c.x.back().push_back(8.0 * uniform());
      if (v % 5 != 0) c.surface.back().push_back(v);  // some vertices are interior
    }
  }
  return c;
}

RepulsionParams params_10_12_8() {
  RepulsionParams p;
  p.range = 1.3;
  p.strength = 0.7;
  p.box[0] = 10;
  p.box[1] = 12;
  p.box[2] = 8;
  p.wall_offset = 2.0;
  return p;
}

RepulsionReport evaluate(RepulsionSearch& search, Cloud& c) {
  std::vector<ContactCell> cells(c.x.size());
  for (std::size_t k = 0; k < cells.size(); ++k) {
    std::fill(c.f[k].begin(), c.f[k].end(), 0.0);
    cells[k] = {c.x[k].data(), c.f[k].data(), c.surface[k]};
  }
  return search.add_forces(cells);
}

TEST(Repulsion, ForcesAreMinusTheEnergyGradient) {
  Cloud c = random_cloud(4, 60, 3);
  RepulsionSearch search(params_10_12_8());
  const RepulsionReport base = evaluate(search, c);
  ASSERT_GT(base.vertex_pairs, 10);
  ASSERT_GT(base.wall_vertices, 3);
  const std::vector<std::vector<double>> forces = c.f;
  const double h = 1e-6;
  double worst = 0.0, largest = 0.0;
  for (std::size_t k = 0; k < c.x.size(); ++k) {
    for (std::size_t i = 0; i < c.x[k].size(); ++i) {
      const double x0 = c.x[k][i];
      c.x[k][i] = x0 + h;
      const double ep = evaluate(search, c).energy;
      c.x[k][i] = x0 - h;
      const double em = evaluate(search, c).energy;
      c.x[k][i] = x0;
      const double fd = -(ep - em) / (2 * h);
      worst = std::max(worst, std::abs(fd - forces[k][i]));
      largest = std::max(largest, std::abs(forces[k][i]));
    }
  }
  EXPECT_GT(largest, 0.1);
  EXPECT_LT(worst, 1e-6 * largest + 1e-8);
}

TEST(Repulsion, CellListFindsTheBruteForcePairs) {
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    Cloud c = random_cloud(5, 80, seed);
    const RepulsionParams p = params_10_12_8();
    RepulsionSearch search(p);
    const RepulsionReport report = evaluate(search, c);
    int pairs = 0;
    std::set<std::pair<int, int>> cell_pairs;
    double energy = 0.0;
    for (std::size_t a = 0; a < c.x.size(); ++a) {
      for (std::size_t b = a + 1; b < c.x.size(); ++b) {
        for (int i : c.surface[a]) {
          for (int j : c.surface[b]) {
            double d2 = 0.0;
            for (int d = 0; d < 3; ++d) {
              double r = c.x[a][3 * i + d] - c.x[b][3 * j + d];
              if (d != 1) r -= p.box[d] * std::round(r / p.box[d]);
              d2 += r * r;
            }
            if (d2 < p.range * p.range) {
              ++pairs;
              cell_pairs.insert({static_cast<int>(a), static_cast<int>(b)});
              energy += repulsion_energy(std::sqrt(d2), p.range, p.strength);
            }
          }
        }
      }
    }
    for (std::size_t a = 0; a < c.x.size(); ++a) {
      for (int i : c.surface[a]) {
        const double y = c.x[a][3 * i + 1];
        energy += repulsion_energy(y - p.wall_offset, p.range, p.strength) +
                  repulsion_energy(p.box[1] - p.wall_offset - y, p.range, p.strength);
      }
    }
    EXPECT_EQ(report.vertex_pairs, pairs) << seed;
    EXPECT_EQ(report.contact_pairs, static_cast<int>(cell_pairs.size())) << seed;
    EXPECT_NEAR(report.energy, energy, 1e-12 * (1 + energy)) << seed;
    // Momentum: the pair forces cancel; only the walls push in y.
    double sum[3] = {0, 0, 0};
    for (const auto& f : c.f) {
      for (std::size_t i = 0; i < f.size(); ++i) sum[i % 3] += f[i];
    }
    EXPECT_NEAR(sum[0], 0.0, 1e-12);
    EXPECT_NEAR(sum[2], 0.0, 1e-12);
  }
}

// The Verlet list kept across calls while the vertices drift finds what a
// search rebuilt at every call (skin 0) finds, at every call: the same pairs,
// energy and forces; it is rebuilt only now and then.
TEST(Repulsion, VerletListKeptAcrossCallsFindsWhatAFreshSearchFinds) {
  Cloud c = random_cloud(5, 80, 7);
  RepulsionParams p = params_10_12_8();
  p.skin = 0.4;
  RepulsionSearch kept(p);
  p.skin = 0.0;
  RepulsionSearch fresh(p);
  std::mt19937_64 rng(11);
  auto uniform = [&] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  const int calls = 200;
  int pairs_seen = 0;
  for (int call = 0; call < calls; ++call) {
    // Every vertex drifts by up to 0.02 a component and call (some faster).
    for (auto& x : c.x)
      for (std::size_t i = 0; i < x.size(); ++i) x[i] += (uniform() - 0.5) * (i % 7 == 0 ? 0.12 : 0.04);
    const RepulsionReport a = evaluate(kept, c);
    const std::vector<std::vector<double>> fa = c.f;
    const RepulsionReport b = evaluate(fresh, c);
    ASSERT_EQ(a.vertex_pairs, b.vertex_pairs) << call;
    ASSERT_EQ(a.contact_pairs, b.contact_pairs) << call;
    ASSERT_EQ(a.wall_vertices, b.wall_vertices) << call;
    ASSERT_NEAR(a.energy, b.energy, 1e-12 * (1 + b.energy)) << call;
    ASSERT_EQ(a.min_gap, b.min_gap) << call;
    for (std::size_t k = 0; k < fa.size(); ++k)
      for (std::size_t i = 0; i < fa[k].size(); ++i) ASSERT_NEAR(fa[k][i], c.f[k][i], 1e-12) << call;
    pairs_seen += a.vertex_pairs;
  }
  EXPECT_GT(pairs_seen, 10 * calls);
  EXPECT_EQ(fresh.builds(), calls);
  EXPECT_GT(kept.builds(), 1);
  EXPECT_LT(kept.builds(), calls / 3);
  // A different vertex set rebuilds at once.
  c.surface[0].pop_back();
  const long long before = kept.builds();
  evaluate(kept, c);
  EXPECT_EQ(kept.builds(), before + 1);
}

}  // namespace
}  // namespace cellflow::contact_repulsion
