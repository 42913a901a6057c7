// Shear-flow scene benchmarks.
//
// 1. Cost of the immersed-boundary coupling per time step against the
//    lattice-Boltzmann step (Google Benchmark), for the default cell and box:
//      BM_LatticeStep/threads   lb::collide_stream on the default lattice
//      BM_ElasticForces         compute_elastic_forces (default mesh)
//      BM_SpreadForces          spread_forces (local clear + stencils + spread)
//      BM_AdvectCell            advect_cell (stencils + interpolate + move; one cell alone)
//      BM_CouplingStep/threads  spread_forces + advect_cells as the scene calls them
//                               (advect reuses the stencils of the spread)
//      BM_IbmStencils/threads   ibm::build_stencils of the cell's vertices
//      BM_IbmSpread/threads     ibm::spread with built stencils
//      BM_IbmInterpolate/threads ibm::interpolate with built stencils
//    (counter points_per_cpu_s: vertices per CPU second of the process, all
//    threads; per CPU second is what a loaded machine can quote)
//    followed by a Markdown table of the per-step split (medians of timed
//    blocks, the kernels as the scene calls them: coupling serial, lattice
//    with the OpenMP default).
//      bench_shear_flow [--benchmark_filter=...] [--ca=0.2] [--cpr=6] [--elastic_float=0|1]
//
// 2. Time against error (--study): run_shear_flow at Ca (default 0.2) to a
//    steady D with the default options for each cells_per_radius in the list
//    (default 4,6,8); where 2 x cpr is in the list too, the deviation of D
//    from that run (twice the lattice resolution, same mesh) is printed, and
//    for every run the deviation from Roscoe's lambda = 1 value. Markdown.
//      bench_shear_flow --study [--cpr=4,6,8] [--vertices=1000] [--ca=0.2]
//                       [--max_strain=40] [--threads=0] [--kernel=peskin4]
//
// The machine may be shared: quote medians and the load.
#include <benchmark/benchmark.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "physics/coupling/immersed_cell.h"
#include "physics/elastic/elastic_body.h"
#include "physics/lb/fluid.h"
#include "physics/mesh/sphere_mesh.h"
#include "physics/scenes/shear_flow/shear_flow.h"
#include "physics/units/units.h"

namespace cellflow::scenes {
namespace {

struct Options {
  double ca = 0.2;
  double cpr = ShearFlowNumerics{}.cells_per_radius;
  std::vector<double> cpr_list = {4.0, 6.0, 8.0};
  int vertices = kFlowDefaultVertexCount;
  double max_strain = 40.0;
  int threads = 0;
  ibm::Kernel kernel = ibm::Kernel::kPeskin4;
  int elastic_float = -1;  // --elastic_float=0|1: ShearFlowNumerics::elastic_single_precision; -1: default
  bool study = false;
};

Options& options() {
  static Options o;
  return o;
}

// The bench cell: R = 6 um, E = 10 Pa, nu = 0.48, in water.
ShearFlowParams bench_params(double ca, double cpr, int vertices) {
  ShearFlowParams p;
  p.cell.radius_m = 6e-6;
  p.cell.material.youngs_modulus_pa = 10.0;
  p.cell.material.poisson_ratio = 0.48;
  p.cell.target_vertex_count = vertices;
  p.capillary_number = ca;
  p.numerics.cells_per_radius = cpr;
  p.numerics.ibm_kernel = options().kernel;
  p.numerics.threads = options().threads;
  p.numerics.max_strain = options().max_strain;
  if (options().elastic_float >= 0) p.numerics.elastic_single_precision = options().elastic_float != 0;
  return p;
}

// The default lattice and cell, set up as run_shear_flow does.
struct Coupled {
  ShearFlowSetup setup;
  mesh::TetMesh mesh;
  elastic::ElasticBody body;
  std::unique_ptr<lb::Fluid> fluid;
  coupling::ImmersedCells cells;  // one cell
};

Coupled& coupled() {
  static std::unique_ptr<Coupled> c;
  if (c) return *c;
  c = std::make_unique<Coupled>();
  const ShearFlowParams p = bench_params(options().ca, options().cpr, options().vertices);
  StatusOr<ShearFlowSetup> setup = plan_shear_flow(p);
  if (!setup.ok()) {
    std::fprintf(stderr, "%s\n", setup.status().to_string().c_str());
    std::exit(1);
  }
  c->setup = *setup;
  units::LatticeChoice choice;
  choice.cell_radius_m = p.cell.radius_m;
  choice.cells_per_radius = p.numerics.cells_per_radius;
  choice.relaxation_time = p.numerics.relaxation_time;
  choice.fluid_density_kg_m3 = setup->simulated_density_kg_m3;
  choice.fluid_viscosity_pa_s = p.fluid_viscosity_pa_s;
  const units::Units u = *units::make_units(choice);
  mesh::SphereMeshOptions mo;
  mo.radius_m = p.cell.radius_m;
  mo.target_vertex_count = p.cell.target_vertex_count;
  c->mesh = *mesh::make_sphere_mesh(mo);
  const elastic::Material materials[2] = {p.cell.material, p.cell.material};
  c->body = *elastic::make_elastic_body(c->mesh, materials);
  lb::FluidParams fp;
  fp.nx = setup->nx;
  fp.ny = setup->ny;
  fp.nz = setup->nz;
  fp.tau = p.numerics.relaxation_time;
  const double u_wall = u.velocity_to_lattice(setup->wall_speed_m_per_s);
  fp.lower_wall_velocity = {-u_wall, 0.0, 0.0};
  fp.upper_wall_velocity = {u_wall, 0.0, 0.0};
  fp.force_field = true;
  fp.velocity_field = true;
  fp.precision = p.numerics.single_precision ? lb::Precision::kFloat : lb::Precision::kDouble;
  fp.threads = p.numerics.threads;
  c->fluid = std::make_unique<lb::Fluid>(lb::make_fluid(fp).value());
  lb::update_velocity_field(*c->fluid);
  const double centre[3] = {0.5 * fp.nx, 0.5 * fp.ny, 0.5 * fp.nz};
  coupling::ImmersedCell& immersed = coupling::add_cell(c->cells, c->mesh, c->body, u, centre);
  immersed.elastic_precision = p.numerics.elastic_single_precision ? elastic::ForcePrecision::kFloat
                                                                   : elastic::ForcePrecision::kDouble;
  // A deformed cell (as in a run): stretch along the extensional axis.
  for (std::size_t v = 0; v < c->mesh.num_vertices(); ++v) {
    double* x = &c->cells[0].positions_lattice[3 * v];
    const double r[2] = {x[0] - centre[0], x[1] - centre[1]};
    x[0] = centre[0] + 1.1 * r[0] + 0.1 * r[1];
    x[1] = centre[1] + 0.1 * r[0] + 0.92 * r[1];
  }
  return *c;
}

void BM_LatticeStep(benchmark::State& state) {
  Coupled& c = coupled();
  lb::FluidParams fp = c.fluid->params();
  fp.threads = static_cast<int>(state.range(0));
  lb::Fluid fluid = lb::make_fluid(fp).value();
  for (auto _ : state) lb::collide_stream(fluid);
  state.counters["MLUPS"] = benchmark::Counter(static_cast<double>(fluid.num_nodes()) * 1e-6,
                                               benchmark::Counter::kIsIterationInvariantRate);
  state.counters["nodes"] = static_cast<double>(fluid.num_nodes());
}
BENCHMARK(BM_LatticeStep)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ElasticForces(benchmark::State& state) {
  Coupled& c = coupled();
  for (auto _ : state) benchmark::DoNotOptimize(coupling::compute_elastic_forces(c.cells[0], 1));
  state.counters["vertices"] = static_cast<double>(c.mesh.num_vertices());
  state.counters["tets"] = static_cast<double>(c.mesh.num_tets());
}
BENCHMARK(BM_ElasticForces)->Unit(benchmark::kMicrosecond)->UseRealTime();

void BM_SpreadForces(benchmark::State& state) {
  Coupled& c = coupled();
  coupling::compute_elastic_forces(c.cells[0], 1);
  for (auto _ : state) coupling::spread_forces(c.cells, *c.fluid, options().kernel, 1);
}
BENCHMARK(BM_SpreadForces)->Unit(benchmark::kMicrosecond)->UseRealTime();

void BM_AdvectCell(benchmark::State& state) {
  Coupled& c = coupled();
  const std::vector<double> start = c.cells[0].positions_lattice;
  for (auto _ : state) {
    benchmark::DoNotOptimize(coupling::advect_cell(c.cells[0], *c.fluid, options().kernel, 1));
    state.PauseTiming();
    c.cells[0].positions_lattice = start;
    state.ResumeTiming();
  }
}
BENCHMARK(BM_AdvectCell)->Unit(benchmark::kMicrosecond)->UseRealTime();

// CPU seconds of the whole process (every thread), unlike the benchmark's
// own CPU time, which counts the main thread only.
double process_cpu_s() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// Sets points_per_cpu_s and cpu_us_per_iter from process CPU time.
class ProcessCpu {
 public:
  explicit ProcessCpu(benchmark::State& state) : state_(state), t0_(process_cpu_s()) {}
  void finish(double points) {
    const double cpu = process_cpu_s() - t0_;
    const double n = static_cast<double>(state_.iterations());
    state_.counters["points_per_cpu_s"] = cpu > 0 ? points * n / cpu : 0.0;
    state_.counters["cpu_us_per_iter"] = n > 0 ? 1e6 * cpu / n : 0.0;
  }

 private:
  benchmark::State& state_;
  double t0_;
};

void BM_CouplingStep(benchmark::State& state) {
  Coupled& c = coupled();
  const int threads = static_cast<int>(state.range(0));
  coupling::compute_elastic_forces(c.cells[0], 1);
  const std::vector<double> start = c.cells[0].positions_lattice;
  ProcessCpu cpu(state);
  for (auto _ : state) {
    coupling::spread_forces(c.cells, *c.fluid, options().kernel, threads);
    benchmark::DoNotOptimize(coupling::advect_cells(c.cells, *c.fluid, options().kernel, threads));
    std::copy(start.begin(), start.end(), c.cells[0].positions_lattice.begin());
  }
  cpu.finish(static_cast<double>(start.size() / 3));
}
BENCHMARK(BM_CouplingStep)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond)->UseRealTime();

ibm::Grid bench_grid() {
  return ibm::grid_of(*coupled().fluid);
}

void BM_IbmStencils(benchmark::State& state) {
  Coupled& c = coupled();
  const int threads = static_cast<int>(state.range(0));
  ibm::StencilSet set;
  ProcessCpu cpu(state);
  for (auto _ : state)
    ibm::build_stencils(options().kernel, bench_grid(), c.cells[0].positions_lattice, set, threads);
  cpu.finish(static_cast<double>(c.mesh.num_vertices()));
}
BENCHMARK(BM_IbmStencils)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond)->UseRealTime();

template <class T>
void spread_with(ibm::StencilSet& set, const std::vector<double>& f, lb::Fluid& fluid, int threads) {
  ibm::spread<T>(set, f, fluid.force_field<T>(), threads);
}

void BM_IbmSpread(benchmark::State& state) {
  Coupled& c = coupled();
  const int threads = static_cast<int>(state.range(0));
  coupling::compute_elastic_forces(c.cells[0], 1);
  ibm::StencilSet set;
  ibm::build_stencils(options().kernel, bench_grid(), c.cells[0].positions_lattice, set, 1);
  const bool single = c.fluid->params().precision == lb::Precision::kFloat;
  ProcessCpu cpu(state);
  for (auto _ : state) {
    if (single)
      spread_with<float>(set, c.cells[0].forces_lattice, *c.fluid, threads);
    else
      spread_with<double>(set, c.cells[0].forces_lattice, *c.fluid, threads);
  }
  cpu.finish(static_cast<double>(c.mesh.num_vertices()));
}
BENCHMARK(BM_IbmSpread)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond)->UseRealTime();

void BM_IbmInterpolate(benchmark::State& state) {
  Coupled& c = coupled();
  const int threads = static_cast<int>(state.range(0));
  ibm::StencilSet set;
  ibm::build_stencils(options().kernel, bench_grid(), c.cells[0].positions_lattice, set, 1);
  std::vector<double> u(c.cells[0].positions_lattice.size());
  const lb::Fluid& fluid = *c.fluid;
  const bool single = fluid.params().precision == lb::Precision::kFloat;
  ProcessCpu cpu(state);
  for (auto _ : state) {
    if (single)
      ibm::interpolate<float>(set, fluid.velocity_field<float>(), u, threads);
    else
      ibm::interpolate<double>(set, fluid.velocity_field<double>(), u, threads);
    benchmark::DoNotOptimize(u.data());
  }
  cpu.finish(static_cast<double>(c.mesh.num_vertices()));
}
BENCHMARK(BM_IbmInterpolate)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond)->UseRealTime();

// Median over `blocks` timed blocks of `steps` calls, seconds per call.
template <class F>
double median_seconds(F&& f, int blocks, int steps) {
  std::vector<double> t;
  for (int b = 0; b < blocks; ++b) {
    const auto t0 = std::chrono::steady_clock::now();
    for (int s = 0; s < steps; ++s) f();
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / steps);
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

void print_coupling_table() {
  Coupled& c = coupled();
  const std::vector<double> start = c.cells[0].positions_lattice;
  const double lattice = median_seconds([&] { lb::collide_stream(*c.fluid); }, 7, 20);
  const double elastic = median_seconds([&] { coupling::compute_elastic_forces(c.cells[0], 1); }, 7, 50);
  const double spread =
      median_seconds([&] { coupling::spread_forces(c.cells, *c.fluid, options().kernel, 1); }, 7, 50);
  // As the scene: advect_cells right after spread_forces reuses its stencils.
  const double advect = median_seconds(
      [&] {
        coupling::advect_cells(c.cells, *c.fluid, options().kernel, 1);
        std::copy(start.begin(), start.end(), c.cells[0].positions_lattice.begin());
      },
      7, 50);
  const double coupling = elastic + spread + advect;
  std::printf(
      "\n### Coupling cost per time step (Ca %.3g, %g cells/R, lattice %d x %d x %d, %zu vertices, %zu tets, "
      "%s, %s)\n\n",
      options().ca, options().cpr, c.setup.nx, c.setup.ny, c.setup.nz, c.mesh.num_vertices(),
      c.mesh.num_tets(), c.fluid->params().precision == lb::Precision::kFloat ? "float" : "double",
      std::string(ibm::kernel_name(options().kernel)).c_str());
  std::printf("| part | ms per step | / LB step |\n|---|---:|---:|\n");
  auto row = [&](const char* name, double s) {
    std::printf("| %s | %.3f | %.3f |\n", name, 1e3 * s, s / lattice);
  };
  row("LB collide-stream (OpenMP default threads)", lattice);
  row("elastic forces", elastic);
  row("spreading (local clear + spread)", spread);
  row("interpolation + move (stencils of the spread)", advect);
  row("coupling total (elastic + spread + interpolate)", coupling);
}

std::vector<double> parse_list(const char* text) {
  std::vector<double> out;
  const char* p = text;
  while (*p) {
    char* end = nullptr;
    out.push_back(std::strtod(p, &end));
    if (end == p) break;
    p = *end == ',' ? end + 1 : end;
  }
  return out;
}

struct StudyRow {
  double cpr = 0.0;
  ShearFlowResult result;
};

void run_study() {
  const Options& o = options();
  // Roscoe's lambda = 1 column (shared/validation/roscoe_elastic_sphere_shear.csv).
  const std::map<double, double> roscoe_lambda1 = {{0.05, 0.0621}, {0.1, 0.1216}, {0.2, 0.2273},
                                                   {0.4, 0.3821},  {0.8, 0.5646}, {1.0, 0.6135},
                                                   {2.0, 0.7656}};
  const auto roscoe = roscoe_lambda1.find(o.ca);
  std::vector<StudyRow> rows;
  for (const double cpr : o.cpr_list) {
    StudyRow row;
    row.cpr = cpr;
    row.result = run_shear_flow(bench_params(o.ca, cpr, o.vertices));
    const ShearFlowResult& r = row.result;
    std::fprintf(stderr, "cpr %g: %s, stop %s at strain %.2f, D %.5f, %.1f s\n", cpr,
                 r.status.to_string().c_str(), std::string(stop_name(r.stop)).c_str(),
                 r.samples.empty() ? 0.0 : r.samples.back().strain_units, r.steady_taylor_deformation,
                 r.wall_time_s);
    rows.push_back(std::move(row));
  }
  std::printf("\n### Time against error: Ca = %.3g, %d vertices, %s, default options otherwise\n\n", o.ca,
              o.vertices, std::string(ibm::kernel_name(o.kernel)).c_str());
  std::printf(
      "| cells/R | lattice | mesh h/dx | steps | strain at stop | stop | wall s | s/strain | D | incl deg | "
      "tank/gammadot | D - D(2x cells/R) | D / Roscoe(lambda=1) - 1 |\n");
  std::printf("|---:|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const StudyRow& row : rows) {
    const ShearFlowResult& r = row.result;
    const double strain = r.samples.empty() ? 0.0 : r.samples.back().strain_units;
    std::string vs_double = "n/a";
    for (const StudyRow& other : rows) {
      if (std::abs(other.cpr - 2.0 * row.cpr) < 1e-9 && other.result.status.ok()) {
        char buf[64];
        std::snprintf(buf, sizeof buf, "%+.4f (%+.1f %%)",
                      r.steady_taylor_deformation - other.result.steady_taylor_deformation,
                      100.0 * (r.steady_taylor_deformation / other.result.steady_taylor_deformation - 1.0));
        vs_double = buf;
      }
    }
    std::string vs_roscoe = "n/a";
    if (roscoe != roscoe_lambda1.end()) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%+.1f %%",
                    100.0 * (r.steady_taylor_deformation / roscoe->second - 1.0));
      vs_roscoe = buf;
    }
    std::printf("| %g | %dx%dx%d | %.2f | %lld | %.2f | %s | %.1f | %.2f | %.4f | %.2f | %.3f | %s | %s |\n",
                row.cpr, r.setup.nx, r.setup.ny, r.setup.nz, r.mesh_spacing_over_dx,
                static_cast<long long>(r.time_steps), strain,
                r.status.ok() ? std::string(stop_name(r.stop)).c_str() : r.status.to_string().c_str(),
                r.wall_time_s, strain > 0 ? r.wall_time_s / strain : 0.0, r.steady_taylor_deformation,
                r.steady_inclination_deg, r.tank_treading_frequency_per_s / r.setup.shear_rate_per_s,
                vs_double.c_str(), vs_roscoe.c_str());
  }
}

}  // namespace
}  // namespace cellflow::scenes

int main(int argc, char** argv) {
  using cellflow::scenes::options;
  std::vector<char*> rest;
  for (int i = 0; i < argc; ++i) {
    const char* a = argv[i];
    if (std::strcmp(a, "--study") == 0) {
      options().study = true;
    } else if (std::strncmp(a, "--ca=", 5) == 0) {
      options().ca = std::atof(a + 5);
    } else if (std::strncmp(a, "--cpr=", 6) == 0) {
      options().cpr_list = cellflow::scenes::parse_list(a + 6);
      if (!options().cpr_list.empty()) options().cpr = options().cpr_list.front();
    } else if (std::strncmp(a, "--vertices=", 11) == 0) {
      options().vertices = std::atoi(a + 11);
    } else if (std::strncmp(a, "--max_strain=", 13) == 0) {
      options().max_strain = std::atof(a + 13);
    } else if (std::strncmp(a, "--threads=", 10) == 0) {
      options().threads = std::atoi(a + 10);
    } else if (std::strncmp(a, "--elastic_float=", 16) == 0) {
      options().elastic_float = std::atoi(a + 16);
    } else if (std::strncmp(a, "--kernel=", 9) == 0) {
      const auto k = cellflow::ibm::parse_kernel(a + 9);
      if (!k.ok()) {
        std::fprintf(stderr, "%s\n", k.status().message().c_str());
        return 2;
      }
      options().kernel = *k;
    } else {
      rest.push_back(argv[i]);
    }
  }
  if (options().study) {
    cellflow::scenes::run_study();
    return 0;
  }
  int rest_argc = static_cast<int>(rest.size());
  benchmark::Initialize(&rest_argc, rest.data());
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  cellflow::scenes::print_coupling_table();
  return 0;
}
