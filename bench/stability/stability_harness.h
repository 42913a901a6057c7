// Stress matrix of numerical stability (issue 5, item 2): every case runs in
// a child process under a wall-clock limit and must end CONVERGED or FAILED
// with a named cause; HANG (killed at the limit), CRASH (signal, or exit
// without a result) and WRONG (a converged result that fails a sanity check:
// NaN, a non-monotone force curve, a volume change inconsistent with nu, a
// Taylor deformation outside [0, 1)) are the outcomes the matrix exists to
// catch.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "physics/core/status.h"
#include "physics/scenes/quasi_static/quasi_static.h"
#include "physics/scenes/shear_flow/shear_flow.h"

namespace cellflow::stability {

enum class Outcome { kConverged, kFailed, kHang, kCrash, kWrong };
std::string_view outcome_name(Outcome outcome);
// Acceptable for the matrix: CONVERGED, or FAILED with a named cause.
bool acceptable(Outcome outcome, std::string_view cause);

// What a case reports from inside the child process.
struct CaseResult {
  Outcome outcome = Outcome::kCrash;
  std::string cause;   // FAILED: the named cause; WRONG: the failed check
  std::string detail;  // one line: the status message or the key numbers
};

// Where a case may write files (a mesh it generates).
struct CaseContext {
  std::string work_dir;
};

struct Case {
  std::string name;  // unique, "<scene>/<group>/<variant>"
  std::string description;
  double time_limit_s = 120.0;  // wall clock, child killed beyond it (HANG)
  // Anchors must converge: a matrix where everything fails cleanly would
  // otherwise pass. Only the mildest case of each scene is an anchor.
  bool anchor = false;
  std::function<CaseResult(const CaseContext&)> run;
};

// The matrix. Self-test cases (a deliberate hang, crash and wrong number
// that check the harness itself) only with include_self_tests.
std::vector<Case> make_cases(bool include_self_tests);

// The named cause of a failed run from its status ("" when none applies: an
// unnamed failure is not acceptable).
std::string failure_cause(const Status& status);

// Sanity checks of a completed run: the reason it is wrong, or nullopt.
// Compression: every point finite; force positive and strictly increasing;
// F / F_Hertz in [0.3, 10] up to deformation 0.2 (unit or scaling errors); the volume change
// against the virial of the plate forces: at equilibrium
//   sum_i x_i . f_i = sum_e 3 kappa (J_e - 1) J_e V0_e
// (the deviatoric part of paper eq. 5 is traceless), so
//   dV = P - sum_e (J_e - 1)^2 V0_e,  P = -F (Z0 - delta) / (3 kappa):
// with the cell's height H in place of Z0 - delta when the positions are
// known: dV must lie in [P - sum_e (J_e - 1)^2 V0_e, P] (force or volume
// wrong otherwise); no more than 0.1 % of the cell volume may be crushed
// below J = 0.1 without inverting, and dV may not exceed three times P (the
// volumetric term of eq. 5 stays bounded as J -> 0, so a discrete cell can
// collapse locally: a silent wrong number; a lone crushed sliver is not).
// initial_height_m is the mesh's z extent Z0, initial_volume_m3 its volume.
// Per load point, from the positions the scene reports: the smallest element
// volume ratio J_e, sum_e (J_e - 1)^2 V0_e, and the cell's height (z extent:
// the lever arm of the plate forces).
struct ElementVolumes {
  double min_j = 1.0;
  double squared_deviation_m3 = 0.0;
  double height_m = 0.0;
  double crushed_fraction = 0.0;  // reference volume in tets with J_e < 0.1, / V0
};
ElementVolumes element_volumes(const mesh::TetMesh& reference, const double* positions_m);

struct CompressionCheck {
  double initial_height_m = 0.0;
  double initial_volume_m3 = 0.0;
  bool check_volume = true;            // off for a cell with a nucleus (two bulk moduli)
  std::vector<ElementVolumes> points;  // per curve point; empty: not checked
};
std::optional<std::string> check_compression(const scenes::CompressionParams& params,
                                             const scenes::QuasiStaticResult& result,
                                             const CompressionCheck& check);
// Indentation: every point finite, force positive and strictly increasing.
std::optional<std::string> check_indentation(const scenes::QuasiStaticResult& result);
// Shear flow: every sample's D finite and in [0, 1), volume positive and
// within 30 % of the first sample; at Ca <= 0.2 a steady D within a factor 2
// of Roscoe's (5/4) Ca.
std::optional<std::string> check_shear_flow(const scenes::ShearFlowResult& result);

// Result of one case as the parent saw it.
struct CaseRecord {
  std::string name;
  std::string description;
  Outcome outcome = Outcome::kCrash;
  std::string cause;
  std::string detail;
  double wall_s = 0.0;
  bool anchor = false;
};

// Runs `executable --run-case NAME --result-file F --work-dir D` as a child
// process (posix_spawn, stdout/stderr to D/<sanitised name>.log) and waits at
// most time_limit_s: HANG when killed at the limit, CRASH on a signal or an
// exit without a result file.
CaseRecord run_case_in_child(const std::string& executable, const Case& c, const std::string& work_dir,
                             double time_limit_s);

// The child side: runs the case, catches exceptions (reported as CRASH with
// their text), writes the result file. Returns the process exit code.
int run_case_here(const Case& c, const std::string& result_file, const std::string& work_dir);

// Report writers.
std::string markdown_report(const std::vector<CaseRecord>& records, double total_wall_s);
std::string csv_report(const std::vector<CaseRecord>& records);

}  // namespace cellflow::stability
