// Throughput of the elastic force kernel and the tangent assembly on a
// structured tetrahedral box (32^3 cubes x 6 = 196608 tets, 35937 vertices)
// under a random smooth deformation. Counters: tets_per_s (whole call) and
// tets_per_s_per_thread, tets_per_cpu_s (the per-core rate on a shared
// machine). Run with --benchmark_repetitions=5 and quote medians.
// BM_ElasticForcesSimd runs each SIMD copy of the force loop (generic SSE2,
// AVX2, AVX-512; the library picks the best at run time) on one thread.
// The argument float:1 runs the single-precision loop (ForcePrecision::kFloat,
// the flow scenes' default), float:0 the double one.
//
// BM_ElasticForcesFlowCell is the force call of a flow step: the default flow
// cell (sphere of R = 6 um, mesh::kDefaultSphereVertexCount vertices, E = 10 Pa,
// nu = 0.48; w = 1 is the flow scenes' default) under a smooth deformation,
// one thread, small enough to stay in the L2 cache.
//
// BM_ElasticForcesColoured* are the alternative race-free scatter (graph
// colouring of the tets, one parallel loop per colour) measured against the
// library's private per-thread force buffers.
#include <benchmark/benchmark.h>
#include <omp.h>
#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <vector>

#include "physics/elastic/elastic_body.h"
#include "physics/mesh/sphere_mesh.h"
#include "physics/mesh/tet_colouring.h"
#include "tests/elastic/box_mesh.h"

namespace cellflow::elastic {
namespace {

constexpr int kCells = 32;
constexpr double kSize = 10e-6;

struct Scene {
  mesh::TetMesh mesh;
  ElasticBody body;
  std::vector<double> positions;
};

// One scene per Mooney-Rivlin ratio w, built once.
const Scene& scene(double w) {
  static std::map<double, std::unique_ptr<Scene>> scenes;
  auto& slot = scenes[w];
  if (!slot) {
    slot = std::make_unique<Scene>();
    slot->mesh = testing::make_box_mesh(kCells, kCells, kCells, kSize, kSize, kSize);
    const Material materials[] = {Material{1000.0, 0.48, w}};
    slot->body = std::move(make_elastic_body(slot->mesh, materials)).value();
    // y = X + smooth field with 10 % amplitude + a random stretch/shear
    std::mt19937 rng(17);
    std::uniform_real_distribution<double> unit(-1.0, 1.0);
    double g[9];
    for (int k = 0; k < 9; ++k) g[k] = (k % 4 == 0 ? 1.0 : 0.0) + 0.1 * unit(rng);
    slot->positions.resize(slot->mesh.positions_m.size());
    for (std::size_t v = 0; v < slot->mesh.num_vertices(); ++v) {
      const double* x = slot->mesh.positions_m.data() + 3 * v;
      for (int i = 0; i < 3; ++i) {
        slot->positions[3 * v + i] = g[3 * i] * x[0] + g[3 * i + 1] * x[1] + g[3 * i + 2] * x[2] +
                                     0.1 * kSize * std::sin(6.0 * x[(i + 1) % 3] / kSize + i);
      }
    }
  }
  return *slot;
}

double mooney_rivlin_w(const benchmark::State& state) {
  return state.range(1) ? 0.5 : 1.0;
}

// CPU seconds of the whole process (all threads): on a shared machine the
// rate per CPU second is the per-core throughput, whatever else runs.
double process_cpu_seconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

// tets_per_s: wall-clock rate of the whole call; tets_per_s_per_thread: that
// over the thread count; tets_per_cpu_s: per CPU second of all threads.
void set_counters(benchmark::State& state, std::size_t num_tets, int threads, double cpu_seconds) {
  state.counters["tets_per_s"] =
      benchmark::Counter(static_cast<double>(num_tets), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["tets_per_s_per_thread"] = benchmark::Counter(static_cast<double>(num_tets) / threads,
                                                               benchmark::Counter::kIsIterationInvariantRate);
  state.counters["tets_per_cpu_s"] =
      static_cast<double>(num_tets) * static_cast<double>(state.iterations()) / cpu_seconds;
}

ForcePrecision precision_arg(const benchmark::State& state, int index) {
  return state.range(index) ? ForcePrecision::kFloat : ForcePrecision::kDouble;
}

// args: threads, Mooney-Rivlin (0: w = 1 neo-Hookean path, 1: w = 0.5),
// float (1: ForcePrecision::kFloat, the flow scenes' loop)
void BM_ElasticForces(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  const Scene& s = scene(mooney_rivlin_w(state));
  const ForcePrecision precision = precision_arg(state, 2);
  std::vector<double> forces(s.positions.size(), 0.0);
  const double cpu_start = process_cpu_seconds();
  for (auto _ : state) {
    const ElasticEvaluation eval =
        add_elastic_forces(s.body, s.positions.data(), forces.data(), threads, precision);
    benchmark::DoNotOptimize(eval);
    benchmark::ClobberMemory();
  }
  set_counters(state, s.body.num_tets(), threads, process_cpu_seconds() - cpu_start);
}
BENCHMARK(BM_ElasticForces)
    ->ArgNames({"threads", "mooney_rivlin", "float"})
    ->ArgsProduct({{1, 2}, {0, 1}, {0, 1}})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

// One SIMD copy of the force loop on one thread (add_elastic_forces_of_range
// over all tets). args: level (1 generic SSE2, 2 AVX2, 3 AVX-512), Mooney-Rivlin, float.
void BM_ElasticForcesSimd(benchmark::State& state) {
  const TetSimd level = static_cast<TetSimd>(state.range(0));
  if (!tet_simd_supported(level)) {
    state.SkipWithError("SIMD level not supported by this CPU");
    return;
  }
  const Scene& s = scene(mooney_rivlin_w(state));
  const ForcePrecision precision = precision_arg(state, 2);
  const std::int64_t num_tets = static_cast<std::int64_t>(s.body.num_tets());
  std::vector<double> forces(s.positions.size(), 0.0);
  const double cpu_start = process_cpu_seconds();
  for (auto _ : state) {
    const ElasticEvaluation eval =
        add_elastic_forces_of_range(s.body, s.positions.data(), forces.data(), 0, num_tets, level, precision);
    benchmark::DoNotOptimize(eval);
    benchmark::ClobberMemory();
  }
  set_counters(state, s.body.num_tets(), 1, process_cpu_seconds() - cpu_start);
  state.SetLabel(tet_simd_name(level));
}
BENCHMARK(BM_ElasticForcesSimd)
    ->ArgNames({"level", "mooney_rivlin", "float"})
    ->ArgsProduct({{1, 2, 3}, {0, 1}, {0, 1}})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

void BM_ElasticEnergy(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  const Scene& s = scene(mooney_rivlin_w(state));
  const double cpu_start = process_cpu_seconds();
  for (auto _ : state) {
    const ElasticEvaluation eval = elastic_energy(s.body, s.positions.data(), threads);
    benchmark::DoNotOptimize(eval);
  }
  set_counters(state, s.body.num_tets(), threads, process_cpu_seconds() - cpu_start);
}
BENCHMARK(BM_ElasticEnergy)
    ->ArgNames({"threads", "mooney_rivlin"})
    ->Args({1, 0})
    ->Args({1, 1})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

// The default flow cell, one per w, built once (nullptr if meshing failed).
const Scene* flow_cell(double w) {
  static std::map<double, std::unique_ptr<Scene>> scenes;
  auto& slot = scenes[w];
  if (!slot) {
    constexpr double kRadius = 6e-6;
    mesh::SphereMeshOptions options;
    options.radius_m = kRadius;
    StatusOr<mesh::TetMesh> mesh = mesh::make_sphere_mesh(options);
    if (!mesh.ok()) return nullptr;
    slot = std::make_unique<Scene>();
    slot->mesh = std::move(mesh).value();
    const Material materials[] = {Material{10.0, 0.48, w}};
    slot->body = std::move(make_elastic_body(slot->mesh, materials)).value();
    // an ellipsoid stretched 1.3 x along x plus a 5 % smooth ripple
    slot->positions.resize(slot->mesh.positions_m.size());
    for (std::size_t v = 0; v < slot->mesh.num_vertices(); ++v) {
      const double* x = slot->mesh.positions_m.data() + 3 * v;
      const double scale[3] = {1.3, 1.0 / std::sqrt(1.3), 1.0 / std::sqrt(1.3)};
      for (int i = 0; i < 3; ++i) {
        slot->positions[3 * v + i] =
            scale[i] * x[i] + 0.05 * kRadius * std::sin(3.0 * x[(i + 1) % 3] / kRadius + i);
      }
    }
  }
  return slot.get();
}

// args: Mooney-Rivlin (0: w = 1, the flow default; 1: w = 0.5), float
// (1: ForcePrecision::kFloat, the flow scenes' default loop)
void BM_ElasticForcesFlowCell(benchmark::State& state) {
  const Scene* s = flow_cell(state.range(0) ? 0.5 : 1.0);
  const ForcePrecision precision = precision_arg(state, 1);
  if (s == nullptr) {
    state.SkipWithError("sphere mesh failed");
    return;
  }
  std::vector<double> forces(s->positions.size(), 0.0);
  const double cpu_start = process_cpu_seconds();
  for (auto _ : state) {
    std::fill(forces.begin(), forces.end(), 0.0);  // as the flow step does
    const ElasticEvaluation eval =
        add_elastic_forces(s->body, s->positions.data(), forces.data(), 1, precision);
    benchmark::DoNotOptimize(eval);
    benchmark::ClobberMemory();
  }
  set_counters(state, s->body.num_tets(), 1, process_cpu_seconds() - cpu_start);
  state.counters["tets"] = static_cast<double>(s->body.num_tets());
  state.counters["us_per_call"] =
      benchmark::Counter(1e6 * (process_cpu_seconds() - cpu_start) / static_cast<double>(state.iterations()));
}
BENCHMARK(BM_ElasticForcesFlowCell)
    ->ArgNames({"mooney_rivlin", "float"})
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->UseRealTime()
    ->Unit(benchmark::kMicrosecond);

// The colouring alternative: tets reordered by colour (data permuted so each
// colour streams contiguously), one parallel loop per colour scattering
// straight into the force array.
struct ColouredScene {
  ElasticBody body;  // tets in colour order
  std::vector<std::int64_t> offsets;
};

const ColouredScene& coloured_scene(double w) {
  static std::map<double, std::unique_ptr<ColouredScene>> scenes;
  auto& slot = scenes[w];
  if (!slot) {
    const ElasticBody& body = scene(w).body;
    const mesh::TetColouring colouring = mesh::colour_tets(body.tets, body.num_vertices);
    slot = std::make_unique<ColouredScene>();
    ElasticBody& permuted = slot->body;
    permuted.num_vertices = body.num_vertices;
    permuted.neo_hookean = body.neo_hookean;
    for (const std::int32_t t : colouring.order) {
      permuted.tets.insert(permuted.tets.end(), body.tets.begin() + 4 * t, body.tets.begin() + 4 * t + 4);
      permuted.b_matrix.insert(permuted.b_matrix.end(), body.b_matrix.begin() + 9 * t,
                               body.b_matrix.begin() + 9 * t + 9);
      permuted.ref_volume_m3.push_back(body.ref_volume_m3[t]);
      permuted.mu1_pa.push_back(body.mu1_pa[t]);
      permuted.mu2_pa.push_back(body.mu2_pa[t]);
      permuted.kappa_pa.push_back(body.kappa_pa[t]);
    }
    build_lane_blocks(permuted);
    slot->offsets = colouring.offsets;
  }
  return *slot;
}

// One parallel loop per colour; each thread takes contiguous pieces of the
// colour and runs the library's serial block kernel on them.
void coloured_forces(const ColouredScene& cs, const double* y, double* forces, int threads) {
  constexpr std::int64_t kPiece = 256;
  const std::int64_t num_colours = static_cast<std::int64_t>(cs.offsets.size()) - 1;
  double energy = 0.0;
#pragma omp parallel num_threads(threads) reduction(+ : energy)
  for (std::int64_t c = 0; c < num_colours; ++c) {
    const std::int64_t begin = cs.offsets[c];
    const std::int64_t pieces = (cs.offsets[c + 1] - begin + kPiece - 1) / kPiece;
#pragma omp for schedule(static)
    for (std::int64_t k = 0; k < pieces; ++k) {
      const std::int64_t end = std::min(begin + (k + 1) * kPiece, cs.offsets[c + 1]);
      energy += add_elastic_forces_of_range(cs.body, y, forces, begin + k * kPiece, end).energy_j;
    }
  }
  benchmark::DoNotOptimize(energy);
}

void BM_ElasticForcesColoured(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  const double w = mooney_rivlin_w(state);
  const Scene& s = scene(w);
  const ColouredScene& cs = coloured_scene(w);
  std::vector<double> forces(s.positions.size(), 0.0);
  const double cpu_start = process_cpu_seconds();
  for (auto _ : state) {
    coloured_forces(cs, s.positions.data(), forces.data(), threads);
    benchmark::ClobberMemory();
  }
  set_counters(state, s.body.num_tets(), threads, process_cpu_seconds() - cpu_start);
  state.counters["colours"] = static_cast<double>(cs.offsets.size() - 1);
}
BENCHMARK(BM_ElasticForcesColoured)
    ->ArgNames({"threads", "mooney_rivlin"})
    ->Args({1, 0})
    ->Args({2, 0})
    ->Args({1, 1})
    ->Args({2, 1})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

// Tangent assembly (energy, forces and the sparse K in one pass).
void BM_TangentAssembly(benchmark::State& state) {
  const int threads = static_cast<int>(state.range(0));
  const Scene& s = scene(mooney_rivlin_w(state));
  TangentAssembler assembler(s.body);
  assembler.set_threads(threads);
  std::vector<double> forces(s.positions.size(), 0.0);
  const double cpu_start = process_cpu_seconds();
  for (auto _ : state) {
    const ElasticEvaluation eval = assembler.assemble(s.positions.data(), forces.data());
    benchmark::DoNotOptimize(eval);
    benchmark::ClobberMemory();
  }
  set_counters(state, s.body.num_tets(), threads, process_cpu_seconds() - cpu_start);
  state.counters["nonzeros"] = static_cast<double>(assembler.stiffness().nonZeros());
}
BENCHMARK(BM_TangentAssembly)
    ->ArgNames({"threads", "mooney_rivlin"})
    ->Args({1, 0})
    ->Args({2, 0})
    ->Args({1, 1})
    ->Args({2, 1})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace cellflow::elastic

BENCHMARK_MAIN();
