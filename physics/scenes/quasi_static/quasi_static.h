// Quasi-static contact scenes (paper section 4.2): compression between two
// rigid plates and colloidal-probe indentation. Each load point is solved to
// mechanical equilibrium; the curve is force against deformation with the
// Hertz prediction beside each point (shared/validation/README.md).
//
// Compression: the mesh's bounding box is centred at the origin; the lower
// plate is fixed and the upper plate starts at the penalty's zero-force
// distance from the extreme vertices (first contact, no force at zero travel)
// and moves down by delta = 2 R eps, eps = max_deformation (i+1)/load_points.
// Indentation: the cell rests on the lower plate; a probe on the z axis starts
// where its zero-force surface touches the first vertex and moves down by
// max_indentation_m (i+1)/load_points; deformation = delta / (2R).
// The force is the reaction on the moving plate or probe (z component). The
// solver (physics/solver/equilibrium.h) holds the x-y position of the vertex
// mean and the rotations (no rigid drift or rolling).
// Failure is a result: an invalid field gives kInvalidArgument naming it, a
// bad mesh file the reader's error, a load step that cannot converge after
// max_step_splits halvings kNumericalFailure naming the step, its target
// deformation and the cause; the curve computed so far is kept.
#pragma once

#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "physics/cell/cell_params.h"
#include "physics/core/status.h"
#include "physics/elastic/elastic_body.h"
#include "physics/mesh/sphere_mesh.h"
#include "physics/mesh/tet_mesh.h"

namespace cellflow::scenes {

// How the contact constraint is enforced (physics/solver/load_path.h).
// Measured against the CalculiX plate references (validation/fe/
// compare_cellflow.py, 3000 vertices, 40 points to 0.8, 2026-12-01): the
// augmented Lagrangian removes the penalty's stand-off, which made the
// curves soft at large deformation (w = 1 at 0.74: -1.63 % -> -0.35 %;
// w = 0.5: -2.93 % -> -0.72 %), but at small deformation the stand-off hid
// the coarse contact's stiffness (0.02: +0.95 % -> +2.81 %), Newton fails at
// 0.76 for w = 0.5 (the penalty reaches 0.8) and a curve costs 1.5 x the
// time (w = 1: 11.2 s against 7.3 s). So the penalty stays the default. At
// 12000 vertices (w = 1, to 0.6) the augmented Lagrangian is within 0.5 %
// (-0.19 % at 0.6) where the penalty stalls at -0.84 %: the stand-off is
// the floor of the penalty's mesh convergence.
enum class ContactEnforcement {
  kPenalty,              // the plain penalty: each loaded vertex rests at the gap that balances it
  kAugmentedLagrangian,  // Uzawa updates until the gap error is below contact_gap_tolerance_m
};

// What the probe acts on (physics/contact/rigid_contact.h). Measured against
// the CalculiX references (validation/fe/compare_cellflow.py, 3000
// vertices, augmented Lagrangian): colloidal probe, largest error over
// 0.25-20 um 11.3 % on the vertices, 17.1 % on the surface (+2 to +5 % from
// 4.5 um on, where the vertices are within 2.2 %); small probe over 0.1-2 um
// 13.1 % against 24.1 %. On the surface the curve is smooth and monotone but
// stiff: a flat triangle cannot wrap the sphere, so its vertices stand off
// it (vertices alone let the flat faces cut into it). On the pole-graded
// mesh (pole_spacing_m, growth 0.25) the surface is still +2 % stiffer at
// every depth (colloidal 9.0 % against 6.6 %, small probe 9.8 against
// 7.7 %): the facets' sag h^2 / (8 Rp), inside the probe on the vertices,
// standing off it on the surface. Vertices stay the default.
enum class ProbeContact {
  kVertices,  // the surface vertices (a probe narrower than the mesh spacing slips between them)
  kSurface,   // the closest point of each surface triangle: a continuous surface for any probe radius
};

struct QuasiStaticOptions {
  // ||f||_2 / (E R^2) at equilibrium, f the out-of-balance vertex forces
  // (E of the cytoplasm); in [1e-12, 1e-2]
  double residual_tolerance = 1e-6;
  // Per load step, before the step is split; in [1, 1000]. Past deformation
  // 0.66 (w = 0.25) or 0.76 (w = 0.5) the equilibrium moves to another state
  // (validation/fe/README.md, "w = 0.25 at large deformation") and Newton
  // needs 60-270 iterations to get there; a split does not shorten that way
  // (the state, not the increment, is far), so with 40 every sub-step failed
  // again and the curve stopped at 0.66. With 200: w = 0.25 reaches 0.8,
  // w = 0.5 0.8 without a split (3000 vertices, 40 points).
  int max_newton_iterations = 200;
  int max_step_splits = 10;  // nested halvings of one load step; in [0, 30]
  // Repulsive wall/probe force per surface vertex, k s^2 / r inside the range
  // (s = r - gap <= r), then k (2 s - r) (physics/contact/rigid_contact.h).
  // Unset: derived from E, R and the mesh edge length (contact::default_penalty:
  // r = 5e-3 R, penetration 1e-3 R at the design force) so that penetration
  // stays below 0.5 % of R; a range alone keeps the default force k r at
  // zero gap. Stiffness > 0; range in (0, 0.1 R].
  std::optional<double> contact_stiffness_n_per_m;
  std::optional<double> contact_range_m;
  // OpenMP threads of forces, tangent and CG, in [0, 1024]; 0: what pays for
  // the size (one thread below 6000 vertices, else the OpenMP default; see
  // quasi_static.cc for the measurement).
  int threads = 0;
  // The volumetric term kappa/2 (J - 1)^2 of paper eq. (5): averaged over the
  // tets around each vertex (default; linear tets with their own J lock at
  // nu = 0.48 and converge slowly, see elastic_body.h) or per tet as in the paper.
  elastic::VolumetricTerm volumetric = elastic::VolumetricTerm::kNodalAverage;
  ContactEnforcement contact_enforcement = ContactEnforcement::kPenalty;
  // Largest gap error of a load point with the augmented Lagrangian: |gap|
  // of each contact that carries force, the penetration of any other. Unset:
  // kDefaultGapToleranceRadii R. In [1e-8, 1e-2] R.
  std::optional<double> contact_gap_tolerance_m;
  ProbeContact probe_contact = ProbeContact::kVertices;
  // Surface edge length of the generated sphere at its poles, where the
  // plates and the probe touch (mesh::PoleGrading; a mesh file is used as
  // it is). Unset: indentation grades to the contact radius of the first
  // load point over kPoleSpacingsPerContactRadius where that is below the
  // uniform mesh's spacing (probes smaller than the mesh), compression keeps
  // the uniform mesh; 0: uniform; else in [1e-3, 1] R.
  std::optional<double> pole_spacing_m;
  double pole_grading_growth = mesh::PoleGrading{}.growth;  // in [0.1, 1]
  // Ring vertices moved along their meridians (mesh::PoleGrading::ring_jitter)
  // so contact takes them in one by one; in [0, 1].
  double pole_ring_jitter = mesh::PoleGrading{}.ring_jitter;
  // The finite element. kQuadraticTet: a node at every edge of the linear
  // mesh (on the sphere at the surface), the 10-node tet with the energy of
  // eq. 5 at 4 quadrature points (elastic_body.h); `volumetric` is then not
  // used (the volumetric term is evaluated at each point). The plates and the
  // probe act on every surface node, corners and mid-edge nodes alike (a
  // plane touches the four flat sub-triangles of a 6-node face first at one
  // of their vertices); the probe on the surface acts on those
  // sub-triangles. The default penalty is sized for the node spacing, half
  // the edge length. Measured against the CalculiX references
  // (validation/fe/README.md, "Quadratic tetrahedra", 2026-12-02, 40 points
  // to 0.8, 1000 base vertices): w = 1 within 0.55 % from 0.06 on (linear
  // -4.2 % at 0.06, within 1.3 % from 0.08) but 55 s against 0.9 s CPU;
  // w = 0.25 leaves the CalculiX branch as the linear tet does (-4.4 % at 0.66, -12.6 % at 0.8; linear -1.5
  // %, -10.0 %): the quadratic element does not remove that departure, so the linear tet stays the default.
  elastic::Element element = elastic::Element::kLinearTet;
};

// Surface edges per contact radius at the poles of the default indentation mesh.
inline constexpr double kPoleSpacingsPerContactRadius = 3.0;

// Default gap tolerance of the augmented Lagrangian, in cell radii (see
// quasi_static.cc for the measurement).
inline constexpr double kDefaultGapToleranceRadii = 1e-4;

// Points of a curve after first contact, unless the spec says otherwise.
inline constexpr int kDefaultLoadPoints = 40;

struct CompressionParams {
  cell::CellParams cell;
  double max_deformation = 0.5;          // compression / diameter, in (0, 0.9]
  int load_points = kDefaultLoadPoints;  // points of the curve after first contact, >= 1
  QuasiStaticOptions numerics;
};

struct IndentationParams {
  cell::CellParams cell;
  double probe_radius_m = 0.0;     // > 0
  double max_indentation_m = 0.0;  // total approach after first contact, in (0, 0.9 * 2 R)
  int load_points = kDefaultLoadPoints;
  QuasiStaticOptions numerics;
};

// Every field out of range, named relative to the params ("max_deformation",
// "cell.radius_m", "numerics.threads") with its allowed range.
Violations violations(const CompressionParams& params);
Violations violations(const IndentationParams& params);
// violations(params) as a Status, every field under field_prefix.
Status validate(const CompressionParams& params, std::string_view field_prefix = "compression.");
Status validate(const IndentationParams& params, std::string_view field_prefix = "indentation.");

// Parameters that validate() accepted: what a job holds after its one
// conversion, so that running it validates nothing again. Only check() makes one.
template <class Params>
class Checked;
StatusOr<Checked<CompressionParams>> check(const CompressionParams& params,
                                           std::string_view field_prefix = "compression.");
StatusOr<Checked<IndentationParams>> check(const IndentationParams& params,
                                           std::string_view field_prefix = "indentation.");

template <class Params>
class Checked {
 public:
  const Params& params() const { return params_; }
  // OpenMP threads of the solve (0: the OpenMP default), clamped to
  // [0, 1024] as validate() allows: the one field a caller may set after checking.
  void set_threads(int threads) {
    params_.numerics.threads = threads < 0 ? 0 : (threads > 1024 ? 1024 : threads);
  }

 private:
  friend StatusOr<Checked<CompressionParams>> check(const CompressionParams&, std::string_view);
  friend StatusOr<Checked<IndentationParams>> check(const IndentationParams&, std::string_view);
  explicit Checked(Params params) : params_(std::move(params)) {}
  Params params_;
};

// One point of a force-deformation curve.
struct CurvePoint {
  int index = 0;                // 0 .. load_points-1
  double deformation = 0.0;     // compression: delta / (2R); indentation: delta / (2R)
  double displacement_m = 0.0;  // plate or probe travel since first contact
  double force_n = 0.0;         // total reaction on the moving plate or probe
  double hertz_force_n = 0.0;   // Hertz prediction at the same displacement
  double taylor_deformation = 0.0;
  double semi_axes_m[3] = {0, 0, 0};
  double volume_m3 = 0.0;
  double elastic_energy_j = 0.0;
  double max_penetration_m = 0.0;  // deepest vertex (probe: triangle) beyond a plate/probe surface
  double gap_error_m = 0.0;        // augmented Lagrangian: largest |gap| of a loaded contact at the end
  int contact_updates = 0;         // augmented-Lagrangian (Uzawa) updates of this point
  int newton_iterations = 0;       // all Newton iterations of this point (sub-steps included)
  int cg_iterations = 0;           // conjugate-gradient iterations of this point
  int step_splits = 0;             // halvings of this load step
  double residual = 0.0;           // final relative residual
};

// Hooks a caller (cellflow-run, the worker) passes in. All optional.
struct SceneCallbacks {
  std::function<void(const CurvePoint&)> on_point;        // after each load point
  std::function<void(double fraction_done)> on_progress;  // 0..1
  std::function<bool()> should_stop;                      // true: stop, result kCancelled
  // Called with the mesh once and with positions at each load point.
  std::function<void(const mesh::TetMesh&)> on_mesh;
  std::function<void(int index, std::span<const double> positions_m)> on_positions;
};

struct QuasiStaticResult {
  Status status;                  // ok, or the failure naming the load step and cause
  std::vector<CurvePoint> curve;  // every point computed, also on failure
};

QuasiStaticResult run_compression(const CompressionParams& params, const SceneCallbacks& callbacks = {});
QuasiStaticResult run_indentation(const IndentationParams& params, const SceneCallbacks& callbacks = {});
// The same for checked parameters: no validation again.
QuasiStaticResult run_compression(const Checked<CompressionParams>& checked,
                                  const SceneCallbacks& callbacks = {});
QuasiStaticResult run_indentation(const Checked<IndentationParams>& checked,
                                  const SceneCallbacks& callbacks = {});

// The pole spacing an indentation gets without numerics.pole_spacing_m: the
// first load point's smaller Hertz contact radius (probe or plate) over
// kPoleSpacingsPerContactRadius, at least a tenth of the uniform spacing; 0
// (uniform) where the uniform mesh already resolves it or the cell is a mesh
// file.
double default_pole_spacing_m(const IndentationParams& params);

// Hertz forces (shared/validation/README.md).
// Sphere between two plates, total compression delta: F = (4/3) E* R^2 eps^1.5, eps = delta/(2R).
double hertz_plates_force_n(const elastic::Material& m, double radius_m, double compression_m);
// Probe (radius Rp) on a cell resting on a plate, total indentation delta; solves
// d_top + d_bottom = delta with equal force through both contacts.
double hertz_probe_force_n(const elastic::Material& m, double radius_m, double probe_radius_m,
                           double indentation_m);

}  // namespace cellflow::scenes
