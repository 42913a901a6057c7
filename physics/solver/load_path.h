// Quasi-static continuation along a load parameter (plate or probe travel):
// each load step is solved to equilibrium by EquilibriumSolver from a
// predicted state; a step that does not converge is halved, recursively, up
// to a given number of times.
//
// Predictor: the best (lowest Pi under the new obstacles) of
//   - the previous displacement increment extrapolated linearly to the new
//     load, y + (y - y_prev) (t_new - t) / (t - t_prev),
//   - the quadratic through the last three equilibria at t_new (when
//     set_quadratic_predictor is on: the probe curves), and
//   - the current state,
// each also with its contact vertices pushed back along the obstacle normal
// to no deeper inside the penalty range than they were at the last
// equilibrium (entering vertices: half the mean depth of those in contact).
// Inside the range the force grows like depth^2, so a vertex left deep inside
// costs Newton a halving of its excess per iteration; with this predictor a
// load point of the 40-point curve takes 4-6 Newton iterations.
//
// Contact enforcement. With the augmented Lagrangian (ContactEnforcement) the
// path owns the offsets of every constraint (physics/contact/rigid_contact.h)
// and solves each load step as: equilibrium, Uzawa update of the offsets,
// equilibrium again from there, until the gap error (|g| of each constraint
// that carries force, the penetration of every other) is below the
// tolerance. The offsets carry over from one load step to the next (the
// multipliers of the last one are the best guess of the next). The plain
// penalty (no updates) leaves each loaded vertex at the gap where the law
// balances its force.
//
// State check. A caller may reject a converged state that it does not trust
// (the quasi-static scenes: an element crushed below the J guard). The check
// runs on every converged sub-step, not only at the load points: past a
// volume collapse the equilibrium path of eq. 5 loses stability (the
// nu = 0.45 curve near deformation 0.897, docs/stability), Newton then fails
// however short the step, and the halvings would spend the run there
// (10 splits x 200 Newton iterations: 123 s of CPU) to end with a
// non-convergence instead of the collapse that caused it. A rejected state
// ends the load step at once, without halving.
#pragma once

#include <functional>
#include <span>
#include <string>
#include <vector>

#include "physics/contact/rigid_contact.h"
#include "physics/core/status.h"
#include "physics/solver/equilibrium.h"

namespace cellflow::solver {

// The obstacles at load parameter t (metres of travel).
using ObstaclesAtLoad = std::function<contact::Obstacles(double load_m)>;

// Why a converged state at load parameter `load_m` is not accepted; empty: accepted.
using StateCheck = std::function<std::string(double load_m, std::span<const double> positions_m)>;

struct ContactEnforcement {
  bool augmented_lagrangian = false;  // false: the plain penalty
  double gap_tolerance_m = 0.0;       // largest gap error at an accepted load step
  int max_updates = 30;               // Uzawa updates per load step before the step counts as failed
};

struct LoadStepReport {
  bool converged = false;
  std::string message;  // the cause when not converged (no step index: the caller adds it)
  FailureCause cause = FailureCause::kNone;
  int newton_iterations = 0;  // all sub-steps and failed attempts
  int cg_iterations = 0;
  bool state_rejected = false;  // the StateCheck refused a converged state (message says why)
  int step_splits = 0;          // halvings used
  int contact_updates = 0;      // Uzawa updates of the offsets (all sub-steps)
  double gap_error_m = 0.0;     // of the final state (augmented Lagrangian), contact::gap_error
  EquilibriumReport last;       // of the final sub-step
};

class LoadPath {
 public:
  // `solver` must outlive the path; `positions_m` is the equilibrium at `load_m`.
  LoadPath(EquilibriumSolver& solver, ObstaclesAtLoad obstacles, std::vector<double> positions_m,
           double load_m, ContactEnforcement enforcement = {});

  // Advances the equilibrium to `target_load_m`. On failure the state stays at
  // the last converged sub-step.
  LoadStepReport advance_to(double target_load_m, int max_step_splits);

  // Applied to every converged sub-step from now on (see the file comment).
  void set_state_check(StateCheck check) { state_check_ = std::move(check); }

  // Adds the quadratic through the last three equilibria to the predictor's
  // candidates (off by default). Measured: on the colloidal probe curve CG
  // 5891 -> 5493; on the README's 40-point compression curve it is chosen
  // often enough to cost more, Newton 324 -> 356 and CG 17,672 -> 19,255.
  void set_quadratic_predictor(bool on) { quadratic_predictor_ = on; }

  const std::vector<double>& positions_m() const { return positions_; }
  double load_m() const { return load_; }

 private:
  bool try_step(double target, int depth, int max_depth, LoadStepReport& report);
  void predict(double target, const contact::Obstacles& obstacles, std::vector<double>& guess) const;
  void push_out_of_obstacles(const contact::Obstacles& obstacles, std::vector<double>& y) const;
  // The obstacles at `load_m` with the offsets attached (augmented Lagrangian).
  contact::Obstacles obstacles_at(double load_m) const;

  EquilibriumSolver* solver_;
  ObstaclesAtLoad obstacles_;
  std::vector<double> positions_, previous_positions_;
  double load_ = 0.0, previous_load_ = 0.0;
  bool has_previous_ = false;
  std::vector<double> older_positions_;  // the equilibrium before previous_positions_
  double older_load_ = 0.0;
  bool has_older_ = false;
  bool quadratic_predictor_ = false;
  ContactEnforcement enforcement_;
  StateCheck state_check_;
  contact::ContactOffsets offsets_, previous_offsets_;  // at the current and the previous equilibrium
};

}  // namespace cellflow::solver
