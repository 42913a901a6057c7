// Suspension benchmarks (issue 15, performance):
//   suspension_bench step  [cells=8 cpr=6 vertices=1000 strain=0.3 ca=0.2 threads=1 lambda=1 marking_every=1
//                           elastic_float=1 checkpoint=PATH checkpoint_every_s=300 resume=PATH]
//     time per step of the 5 x 8 x 4 R box with `cells` cells at the default
//     resolution, split into LB, elastic forces, interpolation + spreading,
//     contact search + forces, marking (none at lambda = 1) and observables;
//     elastic_float=0 the double elastic loop (numerics.flow.elastic_single_precision).
//     checkpoint=PATH writes a checkpoint at the first checkpoint step after
//     each checkpoint_every_s of wall time (0: at every one) and prints its
//     size and its wall and CPU time against the time step; resume=PATH
//     resumes from one (a run of the same arguments).
//   suspension_bench contact [max_cells=32 vertices=1000 cpr=6 reps=200 phi=0.22]
//     CPU time of the contact search (RepulsionSearch::add_forces) against
//     the number of cells 1..max_cells at a fixed volume fraction (the box
//     grows along x with the count): a call that rebuilds the Verlet list
//     (the cell-list search) and a call that keeps it, each with a
//     least-squares line t = a + b N.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <map>
#include <string>
#include <vector>

#include "bench/shear_flow/key_value_args.h"
#include "physics/cell/cell_body.h"
#include "physics/core/passive_threads.h"
#include "physics/scenes/suspension/cell_contact.h"
#include "physics/scenes/suspension/placement.h"
#include "physics/scenes/suspension/suspension.h"

namespace {

using namespace cellflow;

constexpr double kRadius = 6e-6;

scenes::SuspensionParams box_params(int cells, double cpr, int vertices, double ca, double strain,
                                    int threads) {
  scenes::SuspensionParams p;
  scenes::SuspendedCellKind kind;
  kind.cell.radius_m = kRadius;
  kind.cell.material.youngs_modulus_pa = 10.0;
  kind.cell.material.poisson_ratio = 0.48;
  kind.cell.target_vertex_count = vertices;
  kind.count = cells;
  p.kinds.push_back(kind);
  p.capillary_number = ca;
  p.numerics.flow.cells_per_radius = cpr;
  p.numerics.flow.max_strain = strain;
  p.numerics.flow.snapshot_every_strain = 0.0;
  p.numerics.flow.threads = threads;
  p.numerics.average_after_strain = 0.0;
  return p;
}

double thread_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

int step_bench(std::map<std::string, std::string>& args) {
  auto get = [&](const char* key, double fallback) { return bench::number_arg(args, key, fallback); };
  const int cells = static_cast<int>(get("cells", 8));
  scenes::SuspensionParams p = box_params(
      cells, get("cpr", 6.0), static_cast<int>(get("vertices", scenes::kSuspensionDefaultVertexCount)),
      get("ca", 0.2), get("strain", 0.3), static_cast<int>(get("threads", 1)));
  p.kinds[0].viscosity_ratio = get("lambda", 1.0);
  p.numerics.marking_every_steps = static_cast<int>(get("marking_every", 1));
  p.numerics.flow.elastic_single_precision =
      get("elastic_float", p.numerics.flow.elastic_single_precision ? 1 : 0) != 0;
  StatusOr<scenes::PlannedSuspension> planned = scenes::plan_suspension_run(p);
  if (!planned.ok()) {
    std::fprintf(stderr, "%s\n", planned.status().to_string().c_str());
    return 1;
  }
  const scenes::SuspensionSetup& s = planned->setup();
  scenes::SuspensionCallbacks cb;
  int checkpoints = 0;
  double checkpoint_s = 0.0, checkpoint_cpu_s = 0.0, checkpoint_max_s = 0.0, due_cpu_s = 0.0;
  std::uint64_t checkpoint_bytes = 0;
  cb.checkpointing.spec_hash = 1;  // the arguments' run; a checkpoint of other arguments fails on its sizes
  if (args.count("checkpoint")) {
    using Clock = std::chrono::steady_clock;
    const double every_s = get("checkpoint_every_s", 300.0);
    cb.checkpointing.write_path = args["checkpoint"];
    // The write follows a due() that says yes at once: the thread's CPU time between the two is the write's.
    cb.checkpointing.due = [every_s, &due_cpu_s, last = Clock::now()]() mutable {
      if (std::chrono::duration<double>(Clock::now() - last).count() < every_s) return false;
      last = Clock::now();
      due_cpu_s = thread_cpu_seconds();
      return true;
    };
    cb.checkpointing.on_written = [&](const scenes::ShearFlowCheckpointWritten& w) {
      if (!w.status.ok()) {
        std::printf("checkpoint failed: %s\n", w.status.to_string().c_str());
        return;
      }
      ++checkpoints;
      checkpoint_s += w.seconds;
      checkpoint_cpu_s += thread_cpu_seconds() - due_cpu_s;
      checkpoint_max_s = std::max(checkpoint_max_s, w.seconds);
      checkpoint_bytes = w.bytes;
    };
  }
  if (args.count("resume")) cb.checkpointing.resume_path = args["resume"];
  const scenes::SuspensionResult r = scenes::run_suspension(*planned, cb);
  if (!r.status.ok()) {
    std::fprintf(stderr, "%s\n", r.status.to_string().c_str());
    return 1;
  }
  // Only the steps this run took (a resumed one: from its checkpoint on).
  const double steps = static_cast<double>(
      std::max<std::int64_t>(r.time_steps - std::max<std::int64_t>(r.resumed_from_step, 0), 1));
  const double ms = 1e3 / steps;
  const double total = r.lattice_s + r.elastic_s + r.coupling_s + r.contact_s + r.marking_s + r.observables_s;
  std::printf("box %dx%dx%d nodes, %d cells (phi %.3f), %lld steps, wall %.1f s\n", s.flow.nx, s.flow.ny,
              s.flow.nz, s.cell_count, s.volume_fraction, static_cast<long long>(r.time_steps),
              r.wall_time_s);
  std::printf(
      "per step (ms): total %.3f  LB %.3f  elastic %.3f  coupling %.3f  contact %.3f  marking %.3f  "
      "observables %.3f\n",
      total * ms, r.lattice_s * ms, r.elastic_s * ms, r.coupling_s * ms, r.contact_s * ms, r.marking_s * ms,
      r.observables_s * ms);
  std::printf("contact + marking: %.1f %% of the step (lambda %g, marking every %d steps)\n",
              100.0 * (r.contact_s + r.marking_s) / total, p.kinds[0].viscosity_ratio,
              p.numerics.marking_every_steps);
  std::printf("contact list builds %lld, marking updates %lld, full markings %lld (start: %d)\n",
              static_cast<long long>(r.contact_list_builds), static_cast<long long>(r.marking_updates),
              static_cast<long long>(r.marking_full), s.cell_count);
  if (r.resumed_from_step >= 0)
    std::printf("resumed after step %lld\n", static_cast<long long>(r.resumed_from_step));
  if (!r.resume_refused.empty()) std::printf("resume refused: %s\n", r.resume_refused.c_str());
  if (checkpoints > 0) {
    const double step_s = total / steps;
    std::printf(
        "checkpoints %d of %.2f MB: mean %.4f s wall (max %.4f s), %.4f s CPU each = %.1f time steps of "
        "%.2f ms; %.2f %% of the run's wall time\n",
        checkpoints, static_cast<double>(checkpoint_bytes) / 1e6, checkpoint_s / checkpoints,
        checkpoint_max_s, checkpoint_cpu_s / checkpoints, checkpoint_s / checkpoints / step_s, 1e3 * step_s,
        100.0 * checkpoint_s / r.wall_time_s);
  }
  std::printf("CPU time of the process / wall time: see `time`; the split is of wall time\n");
  return 0;
}

double cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// Least squares t = a + b N and its R^2.
void print_fit(const char* what, const std::vector<double>& ns, const std::vector<double>& ts) {
  const double m = static_cast<double>(ns.size());
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < ns.size(); ++i) {
    sx += ns[i];
    sy += ts[i];
    sxx += ns[i] * ns[i];
    sxy += ns[i] * ts[i];
  }
  const double b = (m * sxy - sx * sy) / (m * sxx - sx * sx), a = (sy - b * sx) / m;
  double ss_res = 0, ss_tot = 0;
  for (std::size_t i = 0; i < ns.size(); ++i) {
    ss_res += std::pow(ts[i] - a - b * ns[i], 2);
    ss_tot += std::pow(ts[i] - sy / m, 2);
  }
  std::printf("fit (%s): t = %.2f us + %.2f us x N, R^2 = %.4f\n", what, a, b, 1.0 - ss_res / ss_tot);
}

int contact_bench(std::map<std::string, std::string>& args) {
  auto get = [&](const char* key, double fallback) { return bench::number_arg(args, key, fallback); };
  const int max_cells = std::clamp(static_cast<int>(get("max_cells", 32)), 1, 256);
  const double cpr = get("cpr", 6.0), phi = get("phi", 0.22);
  const int reps = std::clamp(static_cast<int>(get("reps", 200)), 1, 100000);
  cell::CellParams cp;
  cp.radius_m = kRadius;
  cp.material.youngs_modulus_pa = 10.0;
  cp.target_vertex_count = static_cast<int>(get("vertices", scenes::kSuspensionDefaultVertexCount));
  StatusOr<cell::CellBody> body =
      cell::build_cell_body(cp, elastic::VolumetricTerm::kPerTet, "cell.", cell::Centring::kVolumeCentroid);
  if (!body.ok()) {
    std::fprintf(stderr, "%s\n", body.status().to_string().c_str());
    return 1;
  }
  std::vector<int> surface;
  for (std::size_t v = 0; v < body->mesh.num_vertices(); ++v) {
    if (body->mesh.on_surface[v]) surface.push_back(static_cast<int>(v));
  }
  const double dx = kRadius / cpr;
  std::vector<double> ns, ts;
  std::vector<double> kept;
  std::printf(
      "cells  surface_vertices  box_x/R  rebuild_cpu_us_per_call  kept_cpu_us_per_call  vertex_pairs\n");
  for (int n = 1; n <= max_cells; n = n < 4 ? n + 1 : n + 4) {
    // Box 8 R high, 4 R deep, long enough in x for phi.
    const double lx = n * 4.0 / 3.0 * 3.14159265358979 / (phi * 8.0 * 4.0);
    scenes::placement::PlacementBox box;
    box.size_m = {std::max(lx, 3.0) * kRadius, 8.0 * kRadius, 4.0 * kRadius};
    box.cell_gap_m = 0.5 * dx;
    box.wall_gap_m = 3.0 * dx;
    scenes::placement::PlacementKind kind;
    kind.radius_m = kRadius;
    kind.random_count = n;
    kind.count_field = "count";
    StatusOr<std::vector<scenes::CellPlacement>> placed = scenes::placement::place_cells(box, {kind}, 1);
    if (!placed.ok()) {
      std::fprintf(stderr, "%s\n", placed.status().to_string().c_str());
      return 1;
    }
    std::vector<std::vector<double>> x(n), f(n);
    for (int c = 0; c < n; ++c) {
      const std::array<double, 9> q = scenes::placement::rotation_matrix((*placed)[c].rotation_rad);
      const std::vector<double>& ref = body->mesh.positions_m;
      x[c].resize(ref.size());
      f[c].assign(ref.size(), 0.0);
      for (std::size_t v = 0; v < ref.size() / 3; ++v) {
        for (int a = 0; a < 3; ++a) {
          x[c][3 * v + a] = ((*placed)[c].centre_m[a] + q[3 * a] * ref[3 * v] +
                             q[3 * a + 1] * ref[3 * v + 1] + q[3 * a + 2] * ref[3 * v + 2]) /
                            dx;
        }
      }
    }
    contact_repulsion::RepulsionParams rp;
    rp.range = 1.0;
    rp.strength = 1e-3;
    for (int d = 0; d < 3; ++d) rp.box[d] = box.size_m[d] / dx;
    rp.wall_offset = 2.0;
    contact_repulsion::RepulsionSearch search(rp);
    std::vector<contact_repulsion::ContactCell> cells(n);
    for (int c = 0; c < n; ++c) cells[c] = {x[c].data(), f[c].data(), surface};
    contact_repulsion::RepulsionReport report = search.add_forces(cells);  // warm-up
    double t0 = cpu_seconds();
    for (int r = 0; r < reps; ++r) {
      search.invalidate();
      report = search.add_forces(cells);
    }
    const double us = 1e6 * (cpu_seconds() - t0) / reps;
    t0 = cpu_seconds();
    for (int r = 0; r < reps; ++r) report = search.add_forces(cells);
    const double kept_us = 1e6 * (cpu_seconds() - t0) / reps;
    std::printf("%5d  %16zu  %7.2f  %21.2f  %16.2f  %12d\n", n, n * surface.size(), box.size_m[0] / kRadius,
                us, kept_us, report.vertex_pairs);
    ns.push_back(n);
    ts.push_back(us);
    kept.push_back(kept_us);
  }
  print_fit("rebuild", ns, ts);
  print_fit("kept", ns, kept);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  cellflow::ensure_passive_openmp_wait(argv);
  if (argc < 2) {
    std::fprintf(stderr, "usage: suspension_bench step|contact [key=value ...]\n");
    return 2;
  }
  const std::string mode = argv[1];
  std::optional<std::map<std::string, std::string>> parsed =
      cellflow::bench::parse_key_value_args(argc - 1, argv + 1);
  if (!parsed) return 2;
  if (mode == "step") return step_bench(*parsed);
  if (mode == "contact") return contact_bench(*parsed);
  std::fprintf(stderr, "unknown mode %s (step or contact)\n", mode.c_str());
  return 2;
}
