// Sphere mesh generation (TetGen, including the vertex-count iteration and the
// sliver pass) and the shape observables on the resulting mesh.
#include <benchmark/benchmark.h>

#include <vector>

#include "physics/mesh/sphere_mesh.h"
#include "physics/observables/shape.h"

namespace {

using cellflow::mesh::SphereMeshOptions;

void BM_MakeSphereMesh(benchmark::State& state) {
  SphereMeshOptions options;
  options.radius_m = 8e-6;
  options.target_vertex_count = static_cast<int>(state.range(0));
  std::size_t vertices = 0;
  for (auto _ : state) {
    auto mesh = cellflow::mesh::make_sphere_mesh(options);
    if (!mesh.ok()) {
      state.SkipWithError(mesh.status().to_string().c_str());
      return;
    }
    vertices = mesh->num_vertices();
    benchmark::DoNotOptimize(mesh->positions_m.data());
  }
  state.counters["vertices"] = static_cast<double>(vertices);
}
BENCHMARK(BM_MakeSphereMesh)->Arg(500)->Arg(3000)->Arg(10000)->Arg(20000)->Unit(benchmark::kMillisecond);

void BM_MakeSphereMeshWithNucleus(benchmark::State& state) {
  SphereMeshOptions options;
  options.radius_m = 8e-6;
  options.nucleus_radius_m = 4e-6;
  options.target_vertex_count = static_cast<int>(state.range(0));
  for (auto _ : state) {
    auto mesh = cellflow::mesh::make_sphere_mesh(options);
    benchmark::DoNotOptimize(mesh.ok());
  }
}
BENCHMARK(BM_MakeSphereMeshWithNucleus)->Arg(3000)->Unit(benchmark::kMillisecond);

void BM_MeasureShape(benchmark::State& state) {
  SphereMeshOptions options;
  options.radius_m = 8e-6;
  options.target_vertex_count = static_cast<int>(state.range(0));
  const auto mesh = cellflow::mesh::make_sphere_mesh(options);
  for (auto _ : state) {
    auto shape = cellflow::observables::measure_shape(*mesh, mesh->positions_m.data());
    benchmark::DoNotOptimize(shape.taylor_deformation);
  }
}
BENCHMARK(BM_MeasureShape)->Arg(3000)->Arg(20000)->Unit(benchmark::kMicrosecond);

void BM_NetStrain(benchmark::State& state) {
  SphereMeshOptions options;
  options.radius_m = 8e-6;
  options.target_vertex_count = static_cast<int>(state.range(0));
  auto mesh = cellflow::mesh::make_sphere_mesh(options);
  // Stretch along x by 1.5 so the pair search is not trivially the sphere's.
  std::vector<double> x = mesh->positions_m;
  for (std::size_t v = 0; v < mesh->num_vertices(); ++v) x[3 * v] *= 1.5;
  for (auto _ : state) {
    benchmark::DoNotOptimize(cellflow::observables::net_strain(*mesh, x.data(), 16e-6));
  }
}
BENCHMARK(BM_NetStrain)->Arg(3000)->Arg(20000)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
