#include "physics/solver/load_path.h"

#include <cmath>
#include <limits>
#include <utility>

namespace cellflow::solver {

LoadPath::LoadPath(EquilibriumSolver& solver, ObstaclesAtLoad obstacles, std::vector<double> positions_m,
                   double load_m)
    : solver_(&solver), obstacles_(std::move(obstacles)), positions_(std::move(positions_m)), load_(load_m) {}

void LoadPath::push_out_of_obstacles(const contact::Obstacles& obstacles, std::vector<double>& y) const {
  // A vertex of the predicted state that lies deeper inside an obstacle's
  // range than it did at the last equilibrium is moved back along the
  // obstacle's normal to that depth s = r - gap, and a vertex entering the
  // range to half the mean depth of the vertices in contact. The penalty force
  // grows like s^2 inside the range, so a vertex left deep inside would cost
  // Newton one halving of its excess depth per iteration.
  const std::span<const std::int32_t> vertices = solver_->contact_vertices();
  const std::size_t m = vertices.size();
  const double range = obstacles.penalty.range_m;
  std::vector<double> gaps(m), normals(3 * m), current_gaps(m), current_normals(3 * m);
  contact::nearest_obstacle(obstacles, vertices, y.data(), gaps.data(), normals.data());
  contact::nearest_obstacle(obstacles_(load_), vertices, positions_.data(), current_gaps.data(),
                            current_normals.data());
  double depth_sum = 0.0;
  int in_contact = 0;
  for (std::size_t k = 0; k < m; ++k) {
    if (current_gaps[k] < range) {
      depth_sum += range - current_gaps[k];
      ++in_contact;
    }
  }
  const double entry_depth = in_contact > 0 ? 0.5 * depth_sum / in_contact : 0.25 * range;
  for (std::size_t k = 0; k < m; ++k) {
    const double depth = range - gaps[k];
    const double allowed = std::max(range - current_gaps[k], entry_depth);
    if (depth <= allowed) continue;
    double* yv = y.data() + 3 * static_cast<std::size_t>(vertices[k]);
    for (int a = 0; a < 3; ++a) yv[a] += (depth - allowed) * normals[3 * k + a];
  }
}

void LoadPath::predict(double target, const contact::Obstacles& obstacles, std::vector<double>& guess) const {
  std::vector<std::vector<double>> candidates;
  if (has_previous_ && load_ != previous_load_) {
    const double ratio = (target - load_) / (load_ - previous_load_);
    std::vector<double> extrapolated(positions_.size());
    for (std::size_t i = 0; i < positions_.size(); ++i) {
      extrapolated[i] = positions_[i] + ratio * (positions_[i] - previous_positions_[i]);
    }
    candidates.push_back(extrapolated);
    push_out_of_obstacles(obstacles, extrapolated);
    candidates.push_back(std::move(extrapolated));
  }
  candidates.push_back(positions_);
  std::vector<double> pushed = positions_;
  push_out_of_obstacles(obstacles, pushed);
  candidates.push_back(std::move(pushed));

  double best = std::numeric_limits<double>::infinity();
  guess = positions_;
  for (std::vector<double>& c : candidates) {
    const double pi = solver_->total_energy(obstacles, c.data());
    if (pi < best) {
      best = pi;
      guess = std::move(c);
    }
  }
}

bool LoadPath::try_step(double target, int depth, int max_depth, LoadStepReport& report) {
  const contact::Obstacles obstacles = obstacles_(target);
  std::vector<double> y;
  predict(target, obstacles, y);
  EquilibriumReport eq = solver_->solve(obstacles, y);
  report.newton_iterations += eq.newton_iterations;
  report.cg_iterations += eq.cg_iterations;
  if (eq.converged) {
    previous_positions_ = std::move(positions_);
    previous_load_ = load_;
    has_previous_ = true;
    positions_ = std::move(y);
    load_ = target;
    report.last = std::move(eq);
    return true;
  }
  if (depth >= max_depth) {
    report.last = std::move(eq);
    return false;
  }
  ++report.step_splits;
  const double middle = 0.5 * (load_ + target);
  return try_step(middle, depth + 1, max_depth, report) && try_step(target, depth + 1, max_depth, report);
}

LoadStepReport LoadPath::advance_to(double target_load_m, int max_step_splits) {
  LoadStepReport report;
  report.converged = try_step(target_load_m, 0, max_step_splits, report);
  if (!report.converged) {
    report.cause = report.last.cause;
    report.message = report.last.message;
    if (report.step_splits > 0)
      report.message += " after " + std::to_string(report.step_splits) + " step splits";
  }
  return report;
}

}  // namespace cellflow::solver
