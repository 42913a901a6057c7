// Hydrodynamic radius of the shear-flow cell's immersed-boundary points from
// their Stokes drag (physics/coupling/sphere_drag.h): the measurement behind
// ShearFlowNumerics.hydrodynamic_radius_offset.
//   ibm_sphere_drag cpr=6 vertices=3000 kernel=peskin4 box=32 shrink=0 tau=1
// shrink: the mesh is scaled to radius R - shrink dx before the measurement.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "bench/shear_flow/key_value_args.h"
#include "physics/core/passive_threads.h"
#include "physics/coupling/sphere_drag.h"
#include "physics/mesh/sphere_mesh.h"

int main(int argc, char** argv) {
  cellflow::ensure_passive_openmp_wait(argv);
  using namespace cellflow;
  std::optional<std::map<std::string, std::string>> parsed = bench::parse_key_value_args(argc, argv);
  if (!parsed) return 2;
  std::map<std::string, std::string>& args = *parsed;
  auto get = [&](const char* key, double fallback) { return bench::number_arg(args, key, fallback); };
  const double cpr = get("cpr", 6.0);
  const double shrink = get("shrink", 0.0);
  mesh::SphereMeshOptions mo;
  mo.radius_m = 6e-6;
  mo.target_vertex_count = static_cast<int>(get("vertices", 3000));
  StatusOr<mesh::TetMesh> m = mesh::make_sphere_mesh(mo);
  if (!m.ok()) {
    std::fprintf(stderr, "%s\n", m.status().to_string().c_str());
    return 1;
  }
  coupling::SphereDragOptions o;
  o.box_nodes = static_cast<int>(get("box", 32));
  o.relaxation_time = get("tau", 1.0);
  o.max_steps = static_cast<int>(get("steps", o.max_steps));
  if (args.count("kernel")) {
    StatusOr<ibm::Kernel> k = ibm::parse_kernel(args["kernel"]);
    if (!k.ok()) {
      std::fprintf(stderr, "%s\n", k.status().message().c_str());
      return 2;
    }
    o.kernel = *k;
  }
  if (get("verbose", 0) != 0) {
    o.on_progress = [](int step, double u, double balance) {
      if (step % 1000 == 0) std::printf("step %d U %.8g tether/drag %.6f\n", step, u, balance);
    };
  }
  // Lattice units: x / dx with dx = R / cpr, scaled to R - shrink dx.
  const double scale = (cpr - shrink) / cpr * cpr / mo.radius_m;
  // shell=1: the surface vertices only (a shell of points, no interior).
  const bool shell = get("shell", 0) != 0;
  std::vector<double> points;
  for (std::size_t v = 0; v < m->num_vertices(); ++v) {
    if (shell && !m->on_surface[v]) continue;
    for (int d = 0; d < 3; ++d) points.push_back(m->positions_m[3 * v + d] * scale);
  }
  if (get("stresslet", 0) != 0) {
    // The paper's box (10 x 15 x 5 R) unless box=nx,ny,nz radii is given.
    double b[3] = {10, 15, 5};
    if (args.count("sbox")) std::sscanf(args["sbox"].c_str(), "%lf,%lf,%lf", &b[0], &b[1], &b[2]);
    coupling::SphereStressletOptions so;
    so.nx = static_cast<int>(std::lround(b[0] * cpr));
    so.ny = static_cast<int>(std::lround(b[1] * cpr));
    so.nz = static_cast<int>(std::lround(b[2] * cpr));
    so.kernel = o.kernel;
    so.relaxation_time = o.relaxation_time;
    so.steps = static_cast<int>(get("steps", 8000));
    so.rotating = get("rotating", 1) != 0;
    if (get("verbose", 0) != 0) {
      so.on_progress = [](int step, double a) { std::printf("step %d a_S %.5f\n", step, a); };
    }
    StatusOr<coupling::SphereStressletResult> st = coupling::measure_sphere_stresslet(points, so);
    if (!st.ok()) {
      std::fprintf(stderr, "%s\n", st.status().to_string().c_str());
      return 1;
    }
    std::printf(
        "stresslet: cpr %g vertices %zu kernel %s box %dx%dx%d shrink %g steps %d: a_S %.4f dx (a_S - R = "
        "%+.4f dx), rotlet a_T %.4f dx (%+.4f dx)\n",
        cpr, points.size() / 3, std::string(ibm::kernel_name(o.kernel)).c_str(), so.nx, so.ny, so.nz, shrink,
        st->steps, st->stresslet_radius, st->stresslet_radius - cpr, st->rotlet_radius,
        st->rotlet_radius - cpr);
    return 0;
  }
  StatusOr<coupling::SphereDragResult> r = coupling::measure_sphere_drag(points, o);
  if (!r.ok()) {
    std::fprintf(stderr, "%s\n", r.status().to_string().c_str());
    return 1;
  }
  std::printf(
      "cpr %g vertices %zu kernel %s box %d shrink %g: a_h %.4f dx (mesh radius %.4f dx), a_h - R = %+.4f "
      "dx, "
      "steps %d converged %d tether/drag %.6f\n",
      cpr, points.size() / 3, std::string(ibm::kernel_name(o.kernel)).c_str(), o.box_nodes, shrink,
      r->hydrodynamic_radius, cpr - shrink, r->hydrodynamic_radius - cpr, r->steps, r->converged ? 1 : 0,
      -r->tether_force / r->drag);
  return 0;
}
