#include "physics/solver/load_path.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "physics/core/violations.h"

namespace cellflow::solver {

LoadPath::LoadPath(EquilibriumSolver& solver, ObstaclesAtLoad obstacles, std::vector<double> positions_m,
                   double load_m, ContactEnforcement enforcement)
    : solver_(&solver),
      obstacles_(std::move(obstacles)),
      positions_(std::move(positions_m)),
      load_(load_m),
      enforcement_(enforcement) {
  if (enforcement_.augmented_lagrangian) {
    const contact::Obstacles o = obstacles_(load_);
    const std::size_t probe_constraints =
        o.probe_triangles.empty() ? solver_->contact_vertices().size() : o.probe_triangles.size() / 3;
    offsets_ =
        contact::hard_contact_offsets(o.penalty, solver_->contact_vertices().size(), probe_constraints);
  }
}

contact::Obstacles LoadPath::obstacles_at(double load_m) const {
  contact::Obstacles o = obstacles_(load_m);
  if (enforcement_.augmented_lagrangian) contact::attach_offsets(offsets_, o);
  return o;
}

void LoadPath::push_out_of_obstacles(const contact::Obstacles& obstacles, std::vector<double>& y) const {
  // A vertex of the predicted state that lies deeper inside an obstacle's
  // range than it did at the last equilibrium is moved back along the
  // obstacle's normal to that depth s = r - gap, and a vertex entering the
  // range to half the mean depth of the vertices in contact. The penalty force
  // grows like s^2 inside the range, so a vertex left deep inside would cost
  // Newton one halving of its excess depth per iteration.
  // Depths are compared as fractions of each law's range: a scene may narrow
  // the range with the load (keeping k r), and then the same force sits at
  // the same s / r.
  const std::span<const std::int32_t> vertices = solver_->contact_vertices();
  const std::size_t m = vertices.size();
  const double range = obstacles.penalty.range_m;
  const contact::Obstacles current = obstacles_at(load_);
  const double current_range = current.penalty.range_m;
  std::vector<double> gaps(m), normals(3 * m), current_gaps(m), current_normals(3 * m);
  contact::nearest_obstacle(obstacles, vertices, y.data(), gaps.data(), normals.data());
  contact::nearest_obstacle(current, vertices, positions_.data(), current_gaps.data(),
                            current_normals.data());
  double depth_sum = 0.0;  // in units of the current range
  int in_contact = 0;
  for (std::size_t k = 0; k < m; ++k) {
    if (current_gaps[k] < current_range) {
      depth_sum += 1.0 - current_gaps[k] / current_range;
      ++in_contact;
    }
  }
  const double entry_depth = range * (in_contact > 0 ? 0.5 * depth_sum / in_contact : 0.25);
  for (std::size_t k = 0; k < m; ++k) {
    const double depth = range - gaps[k];
    const double allowed = std::max(range * (1.0 - current_gaps[k] / current_range), entry_depth);
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
  if (quadratic_predictor_ && has_older_ && has_previous_ && older_load_ != previous_load_ &&
      previous_load_ != load_ && older_load_ != load_) {
    // y(t) through the last three equilibria (Lagrange): the increments of
    // a Hertz-like contact shrink or grow with the load, which the linear
    // extrapolation misses. Measured (colloidal probe, 4907 vertices, 40
    // points, lagged tangent): chosen at 13 of 40 points, CG 5891 -> 5493.
    const double t0 = older_load_, t1 = previous_load_, t2 = load_;
    const double w0 = (target - t1) * (target - t2) / ((t0 - t1) * (t0 - t2));
    const double w1 = (target - t0) * (target - t2) / ((t1 - t0) * (t1 - t2));
    const double w2 = (target - t0) * (target - t1) / ((t2 - t0) * (t2 - t1));
    std::vector<double> quadratic(positions_.size());
    for (std::size_t i = 0; i < positions_.size(); ++i) {
      quadratic[i] = w0 * older_positions_[i] + w1 * previous_positions_[i] + w2 * positions_[i];
    }
    candidates.push_back(quadratic);
    push_out_of_obstacles(obstacles, quadratic);
    candidates.push_back(std::move(quadratic));
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
  const contact::Obstacles obstacles = obstacles_at(target);  // its offset spans see offsets_
  const contact::ContactOffsets saved = offsets_;
  if (enforcement_.augmented_lagrangian && has_previous_ && load_ != previous_load_) {
    // The multipliers grow with the load as the positions do: extrapolate the
    // offsets of the constraints loaded at both of the last two equilibria
    // (the first solve then lands near the tolerance instead of at the
    // penetration of the whole force increment).
    const double ratio = (target - load_) / (load_ - previous_load_);
    const double floor = obstacles.penalty.range_m;
    auto extrapolate = [&](std::vector<double>& now, const std::vector<double>& before) {
      if (before.size() != now.size()) return;
      for (std::size_t j = 0; j < now.size(); ++j) {
        if (now[j] > -floor && before[j] > -floor)
          now[j] = std::max(now[j] + ratio * (now[j] - before[j]), -floor);
      }
    };
    extrapolate(offsets_.lower_plate, previous_offsets_.lower_plate);
    extrapolate(offsets_.upper_plate, previous_offsets_.upper_plate);
    extrapolate(offsets_.probe, previous_offsets_.probe);
  }
  std::vector<double> y;
  predict(target, obstacles, y);
  EquilibriumReport eq = solver_->solve(obstacles, y);
  report.newton_iterations += eq.newton_iterations;
  report.cg_iterations += eq.cg_iterations;
  if (eq.converged && enforcement_.augmented_lagrangian) {
    // Uzawa: move the law of each constraint by its gap and re-solve from
    // the equilibrium just found, until the gaps are within the tolerance.
    const std::span<const std::int32_t> vertices = solver_->contact_vertices();
    for (int update = 0;; ++update) {
      const double error = contact::gap_error(obstacles, vertices, y.data());
      report.gap_error_m = error;
      if (error <= enforcement_.gap_tolerance_m) break;
      if (update == enforcement_.max_updates) {
        eq.converged = false;
        eq.cause = FailureCause::kNotConverged;
        eq.message = "the contact gap stayed at " + number_text(error) + " m after " +
                     std::to_string(update) + " augmented-Lagrangian updates (tolerance " +
                     number_text(enforcement_.gap_tolerance_m) + " m)";
        break;
      }
      contact::update_offsets(obstacles, vertices, y.data(), offsets_);
      ++report.contact_updates;
      EquilibriumReport again = solver_->solve(obstacles, y);
      report.newton_iterations += again.newton_iterations;
      report.cg_iterations += again.cg_iterations;
      eq = std::move(again);
      if (!eq.converged) break;
    }
  }
  if (eq.converged && state_check_) {
    std::string why = state_check_(target, y);
    if (!why.empty()) {
      offsets_ = saved;
      report.state_rejected = true;
      report.message = std::move(why);
      report.last = std::move(eq);
      return false;  // not halved: a shorter step does not make this state trusted
    }
  }
  if (!eq.converged) offsets_ = saved;
  if (eq.converged) {
    if (has_previous_) {
      older_positions_ = std::move(previous_positions_);
      older_load_ = previous_load_;
      has_older_ = true;
    }
    previous_positions_ = std::move(positions_);
    if (enforcement_.augmented_lagrangian) previous_offsets_ = saved;  // the offsets of the last equilibrium
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
  if (!report.converged && report.state_rejected) {
    report.cause = FailureCause::kNone;  // converged, not trusted: the message names why
    if (report.step_splits > 0)
      report.message += " (after " + std::to_string(report.step_splits) + " step splits)";
  } else if (!report.converged) {
    report.cause = report.last.cause;
    report.message = report.last.message;
    if (report.step_splits > 0)
      report.message += " after " + std::to_string(report.step_splits) + " step splits";
  }
  return report;
}

}  // namespace cellflow::solver
