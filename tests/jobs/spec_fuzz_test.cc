// Spec fuzzer (issue 13 item 5): seeded random JobSpecs over every field of
// the four scenes (unset, typical, boundary and hostile values: 0, -0.0,
// denormals, 1e+-300, NaN, +-Inf, INT_MIN/INT_MAX, random bytes, random and
// mutated .msh files). For each spec SceneRegistry::prepare either refuses it
// with a message naming a field of that scene, or accepts it with a finite,
// positive, capped memory estimate. A bounded subset of the accepted specs
// whose cost is small (not changed: chosen) runs to an outcome, within a time
// bound and with its peak memory within the estimate.
//
// CELLFLOW_FUZZ_SPECS (default: CELLFLOW_FUZZ_DEFAULT_SPECS), CELLFLOW_FUZZ_SEED
// (default 1), CELLFLOW_FUZZ_FIRST (first spec index: spec i depends only on
// the seed and i, so a failure is reproduced alone), CELLFLOW_FUZZ_RUNS (most
// runs, default CELLFLOW_FUZZ_DEFAULT_RUNS).
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "jobs/common/result_file.h"
#include "jobs/job_spec.h"
#include "jobs/registry.h"
#include "jobs/suspension/suspension_spec.h"
#include "physics/mesh/sphere_mesh.h"

#ifndef CELLFLOW_FUZZ_DEFAULT_SPECS
#define CELLFLOW_FUZZ_DEFAULT_SPECS 20000
#endif
// The long registration has its own test names (ctest names must differ).
#ifndef CELLFLOW_FUZZ_SUITE
#define CELLFLOW_FUZZ_SUITE SpecFuzz
#endif
#ifndef CELLFLOW_FUZZ_DEFAULT_RUNS
#define CELLFLOW_FUZZ_DEFAULT_RUNS 24
#endif

namespace cellflow::jobs {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// The largest estimate a spec may have: the 1 TiB lattice cap, the baseline and a mesh.
constexpr double kMemoryCapBytes = 2.0 * 1099511627776.0;
// A run of a chosen (small) spec ends within this.
constexpr double kMaxRunSeconds = 120.0;
// Accepted specs cheap enough to run: about one in this many specs (seed 1:
// 309 of 20,000).
constexpr long long kCheapPerSpec = 65;

long long env_or(const char* name, long long fallback) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0' ? std::atoll(v) : fallback;
}

// The spec index being handled, for a crash report.
volatile std::sig_atomic_t g_index = -1;
long long g_seed = 1;

void on_crash(int sig) {
  char line[160];
  const int n = std::snprintf(line, sizeof line,
                              "\nspec fuzz: signal %d at spec index %ld (CELLFLOW_FUZZ_SEED=%lld "
                              "CELLFLOW_FUZZ_FIRST=%ld CELLFLOW_FUZZ_SPECS=1 reproduces it)\n",
                              sig, static_cast<long>(g_index), g_seed, static_cast<long>(g_index));
  if (n > 0) (void)!::write(2, line, static_cast<std::size_t>(n));
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

// The files mesh_file may name: a valid small sphere, mutations of it, random
// bytes, a missing path, a directory and a device.
struct MeshPool {
  std::filesystem::path dir;
  std::vector<std::string> files;

  MeshPool() {
    dir = std::filesystem::temp_directory_path() / ("cellflow_spec_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    mesh::SphereMeshOptions o;
    o.radius_m = 8e-6;
    o.target_vertex_count = 300;
    StatusOr<mesh::TetMesh> m = mesh::make_sphere_mesh(o);
    const std::string valid = (dir / "valid.msh").string();
    if (m.ok() && mesh::write_gmsh_msh(*m, valid).ok()) files.push_back(valid);
    std::string text;
    if (!files.empty()) {
      std::ifstream in(valid, std::ios::binary);
      std::stringstream s;
      s << in.rdbuf();
      text = s.str();
    }
    std::mt19937_64 rng(12345);
    for (int i = 0; i < 24 && !text.empty(); ++i) {
      std::string t = text;
      const int kind = i % 4;
      if (kind == 0) {  // byte flips
        for (int k = 0; k < 1 + i; ++k) t[rng() % t.size()] = static_cast<char>(rng() & 0xff);
      } else if (kind == 1) {  // truncated
        t.resize(rng() % t.size());
      } else if (kind == 2) {  // a number replaced by a hostile one
        static const char* kHostile[] = {"1e300", "-1e300",      "nan",         "inf",        "5e-324",
                                         "-0",    "99999999999", "-2147483648", "2147483647", "0"};
        for (int k = 0; k < 3; ++k) {
          std::size_t at = rng() % t.size();
          while (at < t.size() && !std::isdigit(static_cast<unsigned char>(t[at]))) ++at;
          std::size_t end = at;
          while (end < t.size() && (std::isdigit(static_cast<unsigned char>(t[end])) || t[end] == '.' ||
                                    t[end] == 'e' || t[end] == '-'))
            ++end;
          if (at < t.size()) t.replace(at, end - at, kHostile[rng() % 10]);
        }
      } else {  // a line duplicated or removed
        std::size_t at = t.find('\n', rng() % t.size());
        std::size_t next = at == std::string::npos ? std::string::npos : t.find('\n', at + 1);
        if (next != std::string::npos) {
          if (rng() % 2) {
            t.insert(at, t.substr(at, next - at));
          } else {
            t.erase(at, next - at);
          }
        }
      }
      write(t, "mutated" + std::to_string(i) + ".msh");
    }
    for (int i = 0; i < 8; ++i) {
      std::string t(rng() % 4096, '\0');
      for (char& c : t) c = static_cast<char>(rng() & 0xff);
      if (i % 2) t = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n" + t;
      write(t, "random" + std::to_string(i) + ".msh");
    }
    write("", "empty.msh");
    files.push_back((dir / "missing.msh").string());
    files.push_back(dir.string());
    files.push_back("/dev/zero");
  }
  ~MeshPool() {
    std::error_code ignored;
    std::filesystem::remove_all(dir, ignored);
  }
  void write(const std::string& text, const std::string& name) {
    const std::string path = (dir / name).string();
    std::ofstream(path, std::ios::binary) << text;
    files.push_back(path);
  }
};

// One spec's random choices.
class Gen {
 public:
  Gen(long long seed, long long index)
      : rng_(static_cast<std::uint64_t>(seed) * 0x9E3779B97F4A7C15ull ^
             static_cast<std::uint64_t>(index) * 0xBF58476D1CE4E5B9ull) {
    // Per spec: how hostile its fields are (mostly valid specs reach the runs).
    static const double kRates[] = {0.0, 0.03, 0.1, 0.4};
    hostile_ = kRates[rng_() % 4];
  }

  double uniform() { return std::uniform_real_distribution<double>(0.0, 1.0)(rng_); }
  bool chance(double p) { return uniform() < p; }
  std::uint64_t below(std::uint64_t n) { return rng_() % n; }

  // A hostile double.
  double special() {
    static const double kSpecial[] = {0.0,
                                      -0.0,
                                      5e-324,
                                      -5e-324,
                                      1e-300,
                                      1e300,
                                      -1e300,
                                      kNaN,
                                      kInf,
                                      -kInf,
                                      -1.0,
                                      1.0,
                                      2.2250738585072014e-308,
                                      1.7976931348623157e308};
    if (chance(0.3)) {  // log-uniform over 1e-40 .. 1e40 with either sign
      const double v = std::pow(10.0, -40.0 + 80.0 * uniform());
      return chance(0.8) ? v : -v;
    }
    return kSpecial[below(sizeof kSpecial / sizeof kSpecial[0])];
  }
  // A value for a field: typical (mostly) or hostile.
  double real(std::initializer_list<double> typical) {
    if (chance(hostile_)) return special();
    const double* v = typical.begin();
    return v[below(typical.size())];
  }
  int integer(std::initializer_list<int> typical) {
    if (chance(hostile_)) {
      static const int kSpecial[] = {0, -1, 1, INT_MIN, INT_MAX, INT_MAX - 1, INT_MIN + 1, 100000, 1 << 30};
      if (chance(0.3)) return static_cast<int>(rng_());
      return kSpecial[below(sizeof kSpecial / sizeof kSpecial[0])];
    }
    const int* v = typical.begin();
    return v[below(typical.size())];
  }
  // Optional fields are unset this often.
  bool set() { return !chance(0.3); }
  std::string bytes(std::size_t max_len) {
    std::string s(below(max_len + 1), '\0');
    for (char& c : s) c = static_cast<char>(rng_() & 0xff);
    return s;
  }
  double hostile() const { return hostile_; }

 private:
  std::mt19937_64 rng_;
  double hostile_;
};

void fill_material(Gen& g, v1::MaterialSpec* m) {
  if (g.chance(0.97)) m->set_youngs_modulus_pa(g.real({150.0, 1000.0, 10.0, 1e-3, 1e9, 2e3, 50.0}));
  if (g.set()) m->set_poisson_ratio(g.real({0.48, 0.3, 0.45, 0.0, -0.5, 0.49999, -0.999, 0.4999999}));
  if (g.set()) m->set_mooney_rivlin_w(g.real({1.0, 0.0, 0.5, 0.25}));
}

void fill_cell(Gen& g, const MeshPool& pool, v1::CellSpec* c) {
  const double radius = g.real({8e-6, 6e-6, 1e-5, 4e-5, 1e-7, 1e-2, 2.5e-6});
  if (g.chance(0.98)) c->set_radius_m(radius);
  if (g.chance(0.98)) fill_material(g, c->mutable_material());
  if (g.chance(0.15)) {
    c->mutable_nucleus()->set_radius_m(radius * g.real({0.5, 0.3, 0.7, 0.01, 0.99, 1.0}));
    if (g.chance(0.95)) fill_material(g, c->mutable_nucleus()->mutable_material());
  }
  if (g.set()) c->set_target_vertex_count(g.integer({200, 250, 300, 400, 600, 1000, 3000, 20000}));
  if (g.chance(0.06)) {
    c->set_mesh_file(g.chance(0.9) ? pool.files[g.below(pool.files.size())] : g.bytes(64));
  }
}

void fill_quasi_static_numerics(Gen& g, double radius, v1::QuasiStaticNumerics* n) {
  if (g.set()) n->set_residual_tolerance(g.real({1e-6, 1e-4, 1e-8, 1e-12, 1e-2}));
  if (g.set()) n->set_max_newton_iterations(g.integer({40, 10, 1, 100, 1000}));
  if (g.set()) n->set_max_step_splits(g.integer({0, 1, 2, 3, 10, 30}));
  if (g.chance(0.2)) n->set_contact_stiffness_n_per_m(g.real({0.5, 0.05, 1e-3, 10.0, 1e3}));
  if (g.chance(0.2)) n->set_contact_range_m(g.real({5e-3 * radius, 1e-8, 1e-5 * radius, 0.1 * radius}));
  if (g.chance(0.3)) n->set_volumetric_term(static_cast<v1::VolumetricTerm>(g.integer({0, 1, 2, 3, -1})));
}

void fill_compression(Gen& g, const MeshPool& pool, v1::CompressionSpec* s) {
  if (g.chance(0.98)) fill_cell(g, pool, s->mutable_cell());
  if (g.chance(0.97)) s->set_max_deformation(g.real({0.5, 0.1, 0.2, 0.9, 1e-3, 0.3}));
  if (g.set()) s->set_load_points(g.integer({1, 2, 3, 5, 40, 10000}));
  if (g.chance(0.7)) fill_quasi_static_numerics(g, s->cell().radius_m(), s->mutable_numerics());
}

void fill_indentation(Gen& g, const MeshPool& pool, v1::IndentationSpec* s) {
  if (g.chance(0.98)) fill_cell(g, pool, s->mutable_cell());
  const double r = s->cell().radius_m();
  if (g.chance(0.97)) s->set_probe_radius_m(g.real({r, 2.0 * r, 0.5 * r, 5e-6, 26.5e-6, 1e-8, 1e-1}));
  if (g.chance(0.97)) s->set_max_indentation_m(g.real({0.2 * r, 0.5 * r, 1.79 * r, 2e-3 * r, 1e-6}));
  if (g.set()) s->set_load_points(g.integer({1, 2, 3, 5, 40, 10000}));
  if (g.chance(0.7)) fill_quasi_static_numerics(g, r, s->mutable_numerics());
}

void fill_flow_numerics(Gen& g, v1::ShearFlowNumerics* n);

void fill_shear_flow(Gen& g, const MeshPool& pool, v1::ShearFlowSpec* s) {
  if (g.chance(0.98)) fill_cell(g, pool, s->mutable_cell());
  if (g.set()) s->set_fluid_density_kg_m3(g.real({1e3, 1.0, 1e5, 1050.0}));
  if (g.set()) s->set_fluid_viscosity_pa_s(g.real({1e-3, 1e-6, 1e3, 1.2e-3}));
  const std::uint64_t drive = g.below(10);
  if (drive < 5) {
    s->set_capillary_number(g.real({0.05, 0.1, 0.2, 1e-3, 100.0, 1e-6}));
  } else if (drive < 9) {
    s->set_shear_rate_per_s(g.real({4.0, 100.0, 1e3, 1e-6, 1e7}));
  }
  if (g.chance(0.8)) fill_flow_numerics(g, s->mutable_numerics());
}

// The flow numerics a shear-flow and a suspension spec share.
void fill_flow_numerics(Gen& g, v1::ShearFlowNumerics* n) {
  if (g.set()) n->set_cells_per_radius(g.real({2.0, 3.0, 4.0, 6.0, 64.0}));
  if (g.set()) n->set_box_x_radii(g.real({10.0, 4.0, 5.0, 1000.0}));
  if (g.set()) n->set_box_y_radii(g.real({15.0, 5.0, 6.0, 1000.0}));
  if (g.set()) n->set_box_z_radii(g.real({5.0, 4.0, 1000.0}));
  if (g.set()) n->set_relaxation_time(g.real({1.0, 0.9, 0.505, 3.0, 0.75}));
  if (g.set()) n->set_max_mach(g.real({0.1, 0.3, 1e-3, 0.2}));
  if (g.set()) n->set_max_time_s(g.real({0.0, 1.0, 1e-3, 1e7}));
  if (g.set()) n->set_steady_tolerance(g.real({2e-3, 0.0, 0.5}));
  if (g.set()) n->set_steady_window_strain(g.real({2.0, 0.2, 1.0, 1e4}));
  if (g.set()) {
    static const char* kKernels[] = {"peskin4", "peskin3", "trilinear"};
    n->set_ibm_kernel(g.chance(0.8) ? std::string(kKernels[g.below(3)]) : g.bytes(16));
  }
  if (g.set()) n->set_single_precision(g.chance(0.5));
  if (g.set()) n->set_sample_every_strain(g.real({0.1, 1.0, 0.5, 1e-3}));
  if (g.set()) n->set_snapshot_every_strain(g.real({1.0, 0.0, 0.5, 1e-3, 1e4}));
  if (g.set()) n->set_fluid_snapshots(g.chance(0.3));
  if (g.set()) n->set_memory_limit_bytes(g.real({4e9, 1e9, 0.0, -1.0, 1099511627776.0}));
  if (g.set()) n->set_target_reynolds_number(g.real({0.1, 1.0, 0.0, 0.01}));
  if (g.set()) n->set_max_strain(g.real({40.0, 1.0, 0.5, 2.0, 1e4}));
  if (g.set()) n->set_max_stiffness_ratio(g.real({0.0, 2.5, 100.0}));
  if (g.chance(0.3)) n->set_volumetric_term(static_cast<v1::VolumetricTerm>(g.integer({0, 1, 2, 7})));
  if (g.set())
    n->set_boundaries(g.chance(0.8) ? std::string(g.chance(0.5) ? "walls" : "lees_edwards") : g.bytes(16));
}

// A suspension: 1 to 3 kinds (sometimes none, or more than the 64 allowed),
// each counted, given a volume fraction or placed (inside, outside, on top of
// one another), with its own viscosity ratio; the suspension's numerics.
// A small suspension that the scene accepts and that is cheap enough to run:
// one or two kinds of a few coarse cells (counted, by volume fraction or
// placed apart), any lambda, a short run on a coarse lattice. Without it
// almost no random suspension passes every check, and none would run and
// have its peak memory held against the estimate.
void fill_runnable_suspension(Gen& g, v1::SuspensionSpec* s) {
  const int kinds = static_cast<int>(1 + g.below(2));
  const double radius = g.real({6e-6, 8e-6, 4e-6});
  for (int k = 0; k < kinds; ++k) {
    v1::SuspendedCells* cells = s->add_cells();
    v1::CellSpec* c = cells->mutable_cell();
    c->set_radius_m(radius * (k == 0 ? 1.0 : 0.8));
    c->mutable_material()->set_youngs_modulus_pa(
        g.real({50.0, 100.0}));  // the lattice's Mach limit at 3 cells/R
    c->mutable_material()->set_poisson_ratio(0.48);
    c->set_target_vertex_count(g.integer({200, 250, 300}));
    if (g.chance(0.5)) cells->set_viscosity_ratio(g.real({1.0, 0.05, 5.0}));
    if (g.chance(0.2)) {
      // One placed cell per kind, apart from the other kind's.
      v1::CellPlacement* p = cells->add_placements();
      p->set_x_m((1.5 + 2.5 * k) * radius);
      p->set_y_m(4.0 * radius);
      p->set_z_m(2.0 * radius);
    } else if (k == 0 && g.chance(0.3)) {
      cells->set_volume_fraction(0.05);
    } else {
      cells->set_count(1);
    }
  }
  s->set_capillary_number(g.real({0.05, 0.1, 0.2}));
  v1::SuspensionNumerics* n = s->mutable_numerics();
  n->mutable_flow()->set_cells_per_radius(3.0);
  n->mutable_flow()->set_max_strain(g.real({0.1, 0.2}));
  if (g.set()) n->set_seed(static_cast<std::uint64_t>(g.integer({1, 2, 7})));
  if (g.set()) n->set_marking_every_steps(g.integer({1, 5}));
  if (g.set()) n->set_average_after_strain(g.real({0.0, 0.05}));
}

void fill_suspension(Gen& g, const MeshPool& pool, v1::SuspensionSpec* s) {
  if (g.chance(0.15)) {
    fill_runnable_suspension(g, s);
    return;
  }
  const int kinds = g.chance(0.03) ? 0 : g.chance(0.02) ? 65 : static_cast<int>(1 + g.below(2) + g.below(2));
  for (int k = 0; k < kinds; ++k) {
    v1::SuspendedCells* cells = s->add_cells();
    if (g.chance(0.98)) fill_cell(g, pool, cells->mutable_cell());
    const double r = cells->cell().radius_m();
    // Mostly unset or 1: a refused lambda of one kind refuses the whole spec.
    if (g.chance(0.25)) cells->set_viscosity_ratio(g.real({1.0, 1.0, 0.05, 5.0, 0.0, -1.0, 1e3}));
    const std::uint64_t how = g.below(10);
    if (how < 4) {
      cells->set_count(g.integer({1, 2, 4, 8, 0, -1, 1000, INT_MAX}));
    } else if (how < 7) {
      cells->set_volume_fraction(g.real({0.11, 0.22, 0.05, 0.5, 0.6, 0.0, -0.1}));
    } else if (how < 9) {
      const int places = static_cast<int>(1 + g.below(3));
      for (int i = 0; i < places; ++i) {
        v1::CellPlacement* p = cells->add_placements();
        // Inside a 5 x 8 x 4 R box, on a wall, outside it, or where the previous one is.
        p->set_x_m(g.real({2.5 * r, (1.0 + 2.2 * i) * r, -r, 100.0 * r}));
        p->set_y_m(g.real({4.0 * r, 1.5 * r, 0.5 * r, 9.0 * r}));
        p->set_z_m(g.real({2.0 * r, 1.5 * r, -3.0 * r}));
        if (g.chance(0.3)) p->set_rotation_z_rad(g.real({0.5, 3.0, 100.0}));
      }
    }  // else: none of the three
  }
  if (g.set()) s->set_fluid_density_kg_m3(g.real({1e3, 1.0, 1e5}));
  if (g.set()) s->set_fluid_viscosity_pa_s(g.real({1e-3, 1e-6, 1e3}));
  const std::uint64_t drive = g.below(10);
  if (drive < 5) {
    s->set_capillary_number(g.real({0.05, 0.1, 0.2, 0.4, 1e-3, 100.0}));
  } else if (drive < 9) {
    s->set_shear_rate_per_s(g.real({4.0, 100.0, 1e-6, 1e7}));
  }
  if (!g.chance(0.8)) return;
  v1::SuspensionNumerics* n = s->mutable_numerics();
  if (g.chance(0.7)) fill_flow_numerics(g, n->mutable_flow());
  if (g.set()) n->set_seed(static_cast<std::uint64_t>(g.integer({1, 2, 0, INT_MAX})));
  if (g.set()) n->set_contact_range_dx(g.real({1.0, 0.5, 4.0, 5.0, 0.0}));
  if (g.set()) n->set_contact_strength(g.real({1.0, 10.0, 1e3, 1e4, 0.0}));
  if (g.set()) n->set_average_after_strain(g.real({5.0, 0.0, 1.0, -1.0}));
  if (g.set()) n->set_target_standard_error(g.real({0.0, 0.02, 0.5, 1.0, -0.1}));
  if (g.set()) n->set_marking_every_steps(g.integer({1, 10, 1000, 0, 1001}));
  if (g.set()) n->set_min_gap_dx(g.real({1.0, 0.0, 10.0, 11.0}));
}

v1::JobSpec make_spec(long long seed, long long index, const MeshPool& pool) {
  Gen g(seed, index);
  v1::JobSpec spec;
  if (g.chance(0.5)) spec.set_name(g.bytes(24));
  const std::uint64_t scene = g.below(100);
  if (scene < 33) {
    fill_compression(g, pool, spec.mutable_compression());
  } else if (scene < 66) {
    fill_indentation(g, pool, spec.mutable_indentation());
  } else if (scene < 88) {
    fill_shear_flow(g, pool, spec.mutable_shear_flow());
  } else if (scene < 98) {
    fill_suspension(g, pool, spec.mutable_suspension());
  }  // else: no scene
  return spec;
}

// The field a refusal names: the identifier after the scene's prefix.
std::string named_field(const std::string& message, const std::string& prefix) {
  const std::size_t at = message.find(prefix);
  if (at == std::string::npos) return {};
  std::size_t end = at;
  // A suspension names its kinds with an index: "suspension.cells[1].viscosity_ratio".
  while (end < message.size() &&
         (std::isalnum(static_cast<unsigned char>(message[end])) || message[end] == '_' ||
          message[end] == '.' || message[end] == '[' || message[end] == ']'))
    ++end;
  std::string field = message.substr(at, end - at);
  while (!field.empty() && field.back() == '.') field.pop_back();
  return field;
}

std::string scene_prefix(const v1::JobSpec& spec) {
  switch (spec.scene_case()) {
    case v1::JobSpec::kCompression:
      return "compression.";
    case v1::JobSpec::kIndentation:
      return "indentation.";
    case v1::JobSpec::kShearFlow:
      return "shear_flow.";
    case v1::JobSpec::kSuspension:
      return "suspension.";
    default:
      return "scene";
  }
}

// Whether an accepted spec is cheap enough to run here (its cost read from
// the spec, the spec itself unchanged).
bool cheap(const v1::JobSpec& spec) {
  auto small_cell = [](const v1::CellSpec& c) {
    if (!c.mesh_file().empty()) return std::filesystem::file_size(c.mesh_file()) < 200000;
    return c.has_target_vertex_count() && c.target_vertex_count() <= 600;
  };
  auto small_numerics = [](const v1::QuasiStaticNumerics& n) {
    return n.has_max_step_splits() && n.max_step_splits() <= 3 &&
           (!n.has_max_newton_iterations() || n.max_newton_iterations() <= 100);
  };
  switch (spec.scene_case()) {
    case v1::JobSpec::kCompression: {
      const auto& s = spec.compression();
      return small_cell(s.cell()) && s.has_load_points() && s.load_points() <= 5 &&
             small_numerics(s.numerics());
    }
    case v1::JobSpec::kIndentation: {
      const auto& s = spec.indentation();
      return small_cell(s.cell()) && s.has_load_points() && s.load_points() <= 5 &&
             small_numerics(s.numerics());
    }
    case v1::JobSpec::kShearFlow: {
      const auto& s = spec.shear_flow();
      if (!small_cell(s.cell())) return false;
      StatusOr<scenes::ShearFlowParams> p = convert(s);
      if (!p.ok()) return false;
      StatusOr<scenes::ShearFlowSetup> plan = scenes::plan_shear_flow(*p);
      if (!plan.ok()) return false;
      double steps = p->numerics.max_strain * plan->steps_per_strain;
      if (p->numerics.max_time_s > 0.0) steps = std::min(steps, p->numerics.max_time_s / plan->time_step_s);
      const double nodes = static_cast<double>(plan->nx) * plan->ny * plan->nz;
      return nodes * steps <= 3e7 && steps <= 20000;
    }
    case v1::JobSpec::kSuspension: {
      const auto& s = spec.suspension();
      for (const auto& kind : s.cells()) {
        if (!small_cell(kind.cell())) return false;
      }
      StatusOr<scenes::PlannedSuspension> planned = plan(s);
      if (!planned.ok()) return false;
      const scenes::ShearFlowSetup& flow = planned->setup().flow;
      const auto& n = planned->params().numerics.flow;
      double steps = n.max_strain * flow.steps_per_strain;
      if (n.max_time_s > 0.0) steps = std::min(steps, n.max_time_s / flow.time_step_s);
      const double nodes = static_cast<double>(flow.nx) * flow.ny * flow.nz;
      return planned->setup().cell_count <= 4 && nodes * steps <= 3e7 && steps <= 20000;
    }
    default:
      return false;
  }
}

// Resident bytes of this process now.
long rss_bytes() {
  long pages = 0, resident = 0;
  if (std::FILE* f = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = 0;
    std::fclose(f);
  }
  return resident * ::sysconf(_SC_PAGESIZE);
}

struct ChildRun {
  int signal = 0;          // the child died of it
  bool timed_out = false;  // killed after the time bound
  int code = -1;           // StatusCode of the run
  std::string message;
  double seconds = 0.0;
  long peak_rss_bytes = 0;  // the child's peak resident set
};

// Runs the job in a child process: its own peak RSS (wait4), a crash or a
// hang is a result here rather than the end of the fuzzer.
ChildRun run_in_child(PreparedJob& job, double timeout_s) {
  ChildRun r;
  int fds[2];
  if (::pipe(fds) != 0) return r;
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    std::ostringstream csv;
    const CsvSink sink{csv, nullptr};
    const Status s = job.run_csv(sink, 1);
    const std::string out = std::to_string(static_cast<int>(s.code())) + "\n" + s.message();
    (void)!::write(fds[1], out.data(), out.size());
    ::_exit(0);
  }
  ::close(fds[1]);
  std::string out;
  char buffer[4096];
  for (;;) {
    const double left =
        timeout_s - std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (left <= 0.0) {
      r.timed_out = true;
      ::kill(pid, SIGKILL);
      break;
    }
    pollfd p{fds[0], POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(left * 1000) + 1) <= 0) continue;
    const ssize_t n = ::read(fds[0], buffer, sizeof buffer);
    if (n <= 0) break;
    out.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(fds[0]);
  int status = 0;
  rusage usage{};
  ::wait4(pid, &status, 0, &usage);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.peak_rss_bytes = usage.ru_maxrss * 1024L;
  if (WIFSIGNALED(status) && !r.timed_out) r.signal = WTERMSIG(status);
  const std::size_t eol = out.find('\n');
  if (eol != std::string::npos) {
    r.code = std::atoi(out.substr(0, eol).c_str());
    r.message = out.substr(eol + 1);
  }
  return r;
}

TEST(CELLFLOW_FUZZ_SUITE, EveryAcceptedSpecIsRunnableAndEveryRefusalNamesAField) {
  g_seed = env_or("CELLFLOW_FUZZ_SEED", 1);
  const long long count = env_or("CELLFLOW_FUZZ_SPECS", CELLFLOW_FUZZ_DEFAULT_SPECS);
  const long long first = env_or("CELLFLOW_FUZZ_FIRST", 0);
  const long long max_runs = env_or("CELLFLOW_FUZZ_RUNS", CELLFLOW_FUZZ_DEFAULT_RUNS);
  for (int sig : {SIGSEGV, SIGABRT, SIGFPE, SIGBUS, SIGILL}) std::signal(sig, on_crash);

  const MeshPool pool;
  ASSERT_FALSE(pool.files.empty());
  const SceneRegistry registry;
  std::map<std::string, long long> refused_by_field, outcomes, accepted_by_scene, run_by_scene;
  std::vector<std::string> failed_examples;
  long long refused = 0, accepted = 0, runs = 0, cheap_seen = 0, failures = 0;
  const auto start = std::chrono::steady_clock::now();
  double run_seconds = 0.0;

  for (long long i = first; i < first + count; ++i) {
    g_index = static_cast<std::sig_atomic_t>(i);
    const v1::JobSpec spec = make_spec(g_seed, i, pool);
    const std::string prefix = scene_prefix(spec);
    StatusOr<std::unique_ptr<PreparedJob>> job = registry.prepare(spec);
    if (!job.ok()) {
      ++refused;
      const Status& s = job.status();
      const std::string field = named_field(s.message(), prefix);
      refused_by_field[field.empty() ? "(none)" : field]++;
      const bool code_ok =
          s.code() == StatusCode::kInvalidArgument || s.code() == StatusCode::kResourceExhausted;
      if (!code_ok || field.empty()) {
        ++failures;
        ADD_FAILURE() << "spec " << i << " (" << status_code_name(s.code()) << ") refused without naming a "
                      << prefix << " field: " << s.message() << "\n"
                      << spec.DebugString();
      }
      if (failures > 20) break;
      continue;
    }
    ++accepted;
    accepted_by_scene[std::string((*job)->scene())]++;
    const double bytes = static_cast<double>((*job)->memory_bytes());
    if (!(std::isfinite(bytes) && bytes > 0.0 && bytes < kMemoryCapBytes)) {
      ++failures;
      ADD_FAILURE() << "spec " << i << ": memory_bytes() = " << bytes << "\n" << spec.DebugString();
    }
    if (!cheap(spec)) continue;
    // About 1 spec in kCheapPerSpec is cheap: run every stride-th of them, so
    // that the runs spread over the whole sequence.
    const long long stride = std::max(1LL, count / kCheapPerSpec / std::max(1LL, max_runs));
    if (cheap_seen++ % stride != 0 || runs >= max_runs) continue;
    ++runs;
    run_by_scene[std::string((*job)->scene())]++;
    const long parent_rss = rss_bytes();
    const ChildRun r = run_in_child(**job, kMaxRunSeconds);
    run_seconds += r.seconds;
    if (r.signal != 0 || r.timed_out || r.code < 0) {
      outcomes[r.timed_out ? "timed out" : r.signal != 0 ? "crashed" : "no outcome"]++;
      ADD_FAILURE() << "spec " << i << ": the run " << (r.timed_out ? "timed out" : "crashed") << " (signal "
                    << r.signal << ")\n"
                    << spec.DebugString();
      continue;
    }
    const auto code = static_cast<StatusCode>(r.code);
    outcomes[status_code_name(code)]++;
    if (code != StatusCode::kOk && failed_examples.size() < 8) {
      failed_examples.push_back("spec " + std::to_string(i) + ": " + status_code_name(code) + ": " +
                                r.message.substr(0, 300));
    }
    // The estimate includes a process baseline: the child's peak beyond the
    // parent's resident set at the fork stays within it.
    EXPECT_LE(static_cast<double>(r.peak_rss_bytes - parent_rss), bytes)
        << "spec " << i << ": peak RSS " << r.peak_rss_bytes << " bytes, " << parent_rss << " at the start\n"
        << spec.DebugString();
    if (code != StatusCode::kOk) {
      EXPECT_FALSE(r.message.empty()) << "spec " << i;
      EXPECT_TRUE(code == StatusCode::kNumericalFailure || code == StatusCode::kInvalidArgument ||
                  code == StatusCode::kResourceExhausted || code == StatusCode::kFailedPrecondition)
          << "spec " << i << ": " << status_code_name(code) << ": " << r.message << "\n"
          << spec.DebugString();
      if (code == StatusCode::kInvalidArgument || code == StatusCode::kResourceExhausted) {
        EXPECT_FALSE(named_field(r.message, prefix).empty()) << "spec " << i << ": " << r.message << "\n"
                                                             << spec.DebugString();
      }
    }
  }
  g_index = -1;
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf(
      "spec fuzz: seed %lld, specs %lld (from %lld), refused %lld, accepted %lld, run %lld; "
      "%.1f s (runs %.1f s)\n",
      g_seed, count, first, refused, accepted, runs, seconds, run_seconds);
  std::printf("accepted by scene:");
  for (const auto& [k, v] : accepted_by_scene) std::printf(" %s %lld", k.c_str(), v);
  std::printf("\nrun by scene:");
  for (const auto& [k, v] : run_by_scene) std::printf(" %s %lld", k.c_str(), v);
  std::printf("\nrun outcomes:");
  for (const auto& [k, v] : outcomes) std::printf(" %s %lld", k.c_str(), v);
  std::printf("\ncheap accepted specs %lld; failed runs, first of them:\n", cheap_seen);
  for (const std::string& e : failed_examples) std::printf("  %s\n", e.c_str());
  std::printf("refused by field:\n");
  for (const auto& [k, v] : refused_by_field) std::printf("  %-60s %lld\n", k.c_str(), v);
  std::fflush(stdout);
}

}  // namespace
}  // namespace cellflow::jobs

#ifndef CELLFLOW_FUZZ_LONG
namespace cellflow::jobs {
namespace {

// Regression cases: values the ranges of issue 13 item 5 refuse (accepted
// before; some reached undefined double -> int64 conversions or an infinite
// contact stiffness), each naming its field.
struct Hostile {
  const char* what;
  void (*spoil)(v1::JobSpec&);
  const char* field;
};

v1::JobSpec valid_spec(int scene) {
  v1::JobSpec spec;
  v1::CellSpec* cell = scene == 0   ? spec.mutable_compression()->mutable_cell()
                       : scene == 1 ? spec.mutable_indentation()->mutable_cell()
                                    : spec.mutable_shear_flow()->mutable_cell();
  cell->set_radius_m(8e-6);
  cell->mutable_material()->set_youngs_modulus_pa(150.0);
  cell->set_target_vertex_count(300);
  if (scene == 0) spec.mutable_compression()->set_max_deformation(0.2);
  if (scene == 1) {
    spec.mutable_indentation()->set_probe_radius_m(8e-6);
    spec.mutable_indentation()->set_max_indentation_m(2e-6);
  }
  if (scene == 2) {
    spec.mutable_shear_flow()->set_capillary_number(0.05);
    spec.mutable_shear_flow()->mutable_numerics()->set_cells_per_radius(4.0);
  }
  return spec;
}

const Hostile kHostile[] = {
    {"E 1e300",
     [](v1::JobSpec& s) {
       s.mutable_compression()->mutable_cell()->mutable_material()->set_youngs_modulus_pa(1e300);
     },
     "compression.cell.material.youngs_modulus_pa"},
    {"E 1e-300",
     [](v1::JobSpec& s) {
       s.mutable_compression()->mutable_cell()->mutable_material()->set_youngs_modulus_pa(1e-300);
     },
     "compression.cell.material.youngs_modulus_pa"},
    {"nu 0.5 - 1 ulp",
     [](v1::JobSpec& s) {
       s.mutable_compression()->mutable_cell()->mutable_material()->set_poisson_ratio(0.49999999999999994);
     },
     "compression.cell.material.poisson_ratio"},
    {"nu -1 + 1e-12",
     [](v1::JobSpec& s) {
       s.mutable_compression()->mutable_cell()->mutable_material()->set_poisson_ratio(-1.0 + 1e-12);
     },
     "compression.cell.material.poisson_ratio"},
    {"nucleus 1e-300",
     [](v1::JobSpec& s) {
       auto* n = s.mutable_compression()->mutable_cell()->mutable_nucleus();
       n->set_radius_m(1e-300);
       n->mutable_material()->set_youngs_modulus_pa(150.0);
     },
     "compression.cell.nucleus.radius_m"},
    {"max_deformation 5e-324", [](v1::JobSpec& s) { s.mutable_compression()->set_max_deformation(5e-324); },
     "compression.max_deformation"},
    {"load_points 100000", [](v1::JobSpec& s) { s.mutable_compression()->set_load_points(100000); },
     "compression.load_points"},
    {"load_points x vertices",
     [](v1::JobSpec& s) {
       s.mutable_compression()->set_load_points(5000);
       s.mutable_compression()->mutable_cell()->set_target_vertex_count(20000);
     },
     "compression.load_points"},
    {"contact range 1e-300 (stiffness k r / r = inf)",
     [](v1::JobSpec& s) { s.mutable_compression()->mutable_numerics()->set_contact_range_m(1e-300); },
     "compression.numerics.contact_range_m"},
    {"contact stiffness 1e300",
     [](v1::JobSpec& s) {
       s.mutable_compression()->mutable_numerics()->set_contact_stiffness_n_per_m(1e300);
     },
     "compression.numerics.contact_stiffness_n_per_m"},
    {"contact stiffness 5e-324",
     [](v1::JobSpec& s) {
       s.mutable_compression()->mutable_numerics()->set_contact_stiffness_n_per_m(5e-324);
     },
     "compression.numerics.contact_stiffness_n_per_m"},
    {"probe 1e300", [](v1::JobSpec& s) { s.mutable_indentation()->set_probe_radius_m(1e300); },
     "indentation.probe_radius_m"},
    {"probe 1e-8 m (below 0.01 R)", [](v1::JobSpec& s) { s.mutable_indentation()->set_probe_radius_m(1e-8); },
     "indentation.probe_radius_m"},
    {"indentation 1e-300", [](v1::JobSpec& s) { s.mutable_indentation()->set_max_indentation_m(1e-300); },
     "indentation.max_indentation_m"},
    {"density 1e-300", [](v1::JobSpec& s) { s.mutable_shear_flow()->set_fluid_density_kg_m3(1e-300); },
     "shear_flow.fluid_density_kg_m3"},
    {"viscosity 1e300", [](v1::JobSpec& s) { s.mutable_shear_flow()->set_fluid_viscosity_pa_s(1e300); },
     "shear_flow.fluid_viscosity_pa_s"},
    {"shear rate 5e-324 (steps per strain = inf)",
     [](v1::JobSpec& s) { s.mutable_shear_flow()->set_shear_rate_per_s(5e-324); },
     "shear_flow.shear_rate_per_s"},
    {"shear rate 1e7 /s giving Ca 197",
     [](v1::JobSpec& s) { s.mutable_shear_flow()->set_shear_rate_per_s(1e7); },
     "shear_flow.shear_rate_per_s"},
    {"Ca 1e300", [](v1::JobSpec& s) { s.mutable_shear_flow()->set_capillary_number(1e300); },
     "shear_flow.capillary_number"},
    {"tau 0.5 + 1e-15",
     [](v1::JobSpec& s) {
       s.mutable_shear_flow()->mutable_numerics()->set_relaxation_time(0.500000000000001);
     },
     "shear_flow.numerics.relaxation_time"},
    {"max_mach 5e-324",
     [](v1::JobSpec& s) { s.mutable_shear_flow()->mutable_numerics()->set_max_mach(5e-324); },
     "shear_flow.numerics.max_mach"},
    {"max_time_s 1e300",
     [](v1::JobSpec& s) { s.mutable_shear_flow()->mutable_numerics()->set_max_time_s(1e300); },
     "shear_flow.numerics.max_time_s"},
    {"sample_every_strain 5e-324",
     [](v1::JobSpec& s) { s.mutable_shear_flow()->mutable_numerics()->set_sample_every_strain(5e-324); },
     "shear_flow.numerics.sample_every_strain"},
    {"1e6 samples",
     [](v1::JobSpec& s) {
       s.mutable_shear_flow()->mutable_numerics()->set_sample_every_strain(1e-3);
       s.mutable_shear_flow()->mutable_numerics()->set_max_strain(1e3);
     },
     "shear_flow.numerics.sample_every_strain"},
    {"snapshot_every_strain 5e-324",
     [](v1::JobSpec& s) { s.mutable_shear_flow()->mutable_numerics()->set_snapshot_every_strain(5e-324); },
     "shear_flow.numerics.snapshot_every_strain"},
    {"steady window 1e300",
     [](v1::JobSpec& s) { s.mutable_shear_flow()->mutable_numerics()->set_steady_window_strain(1e300); },
     "shear_flow.numerics.steady_window_strain"},
    {"memory limit 1e300",
     [](v1::JobSpec& s) { s.mutable_shear_flow()->mutable_numerics()->set_memory_limit_bytes(1e300); },
     "shear_flow.numerics.memory_limit_bytes"},
    {"no memory limit, 64 cells per radius in a 1000-radii box",
     [](v1::JobSpec& s) {
       auto* n = s.mutable_shear_flow()->mutable_numerics();
       n->set_memory_limit_bytes(0.0);
       n->set_cells_per_radius(64.0);
       n->set_box_x_radii(1000.0);
       n->set_target_reynolds_number(0.01);
     },
     "shear_flow.numerics.memory_limit_bytes"},
    {"physical density in water: days of lattice work",
     [](v1::JobSpec& s) {
       s.mutable_shear_flow()->mutable_numerics()->set_target_reynolds_number(0.0);
       s.mutable_shear_flow()->mutable_numerics()->set_cells_per_radius(6.0);
       s.mutable_shear_flow()->mutable_cell()->mutable_material()->set_youngs_modulus_pa(1.0);  // Re_p 1e-3
       s.mutable_shear_flow()->mutable_numerics()->set_max_strain(400.0);
       s.mutable_shear_flow()->mutable_numerics()->set_snapshot_every_strain(0.0);
     },
     "shear_flow.numerics.max_strain"},
};

TEST(SpecFuzzRegression, HostileValuesAreRefusedNamingTheirField) {
  const SceneRegistry registry;
  for (int scene = 0; scene < 3; ++scene) {
    const v1::JobSpec base = valid_spec(scene);
    ASSERT_TRUE(registry.prepare(base).ok()) << registry.prepare(base).status().to_string();
  }
  for (const Hostile& h : kHostile) {
    const std::string field = h.field;
    v1::JobSpec spec = valid_spec(field.starts_with("compression")   ? 0
                                  : field.starts_with("indentation") ? 1
                                                                     : 2);
    h.spoil(spec);
    const StatusOr<std::unique_ptr<PreparedJob>> job = registry.prepare(spec);
    ASSERT_FALSE(job.ok()) << h.what;
    EXPECT_TRUE(job.status().code() == StatusCode::kInvalidArgument ||
                job.status().code() == StatusCode::kResourceExhausted)
        << h.what << ": " << job.status().to_string();
    EXPECT_NE(job.status().message().find(field), std::string::npos)
        << h.what << ": " << job.status().message();
  }
}

// Found by the fuzzer (seed 1, spec 1512): a long, thin lattice run to zero
// steps peaked 60 MB above its estimate: the start profile's two per-node
// doubles were still held while the velocity-field update took three more.
TEST(SpecFuzzRegression, ShearFlowStartStaysWithinTheMemoryEstimate) {
  v1::JobSpec spec = valid_spec(2);
  auto* n = spec.mutable_shear_flow()->mutable_numerics();
  n->set_cells_per_radius(6.0);
  n->set_box_x_radii(5.0);
  n->set_box_y_radii(5.0);
  n->set_box_z_radii(500.0);  // 30 x 30 x 3000 nodes
  n->set_max_strain(1e-300);  // no time step: the start is the peak
  n->set_snapshot_every_strain(0.0);
  const SceneRegistry registry;
  StatusOr<std::unique_ptr<PreparedJob>> job = registry.prepare(spec);
  ASSERT_TRUE(job.ok()) << job.status().to_string();
  const long parent_rss = rss_bytes();
  const ChildRun r = run_in_child(**job, kMaxRunSeconds);
  ASSERT_EQ(r.signal, 0);
  ASSERT_FALSE(r.timed_out);
  EXPECT_EQ(r.code, static_cast<int>(StatusCode::kOk)) << r.message;
  // Without the process baseline (the child shares the parent's pages), with
  // 32 MB for the allocator and the mesh: the old order overran by 65 MB.
  const double estimate = static_cast<double>((*job)->memory_bytes() - kBaselineBytes);
  EXPECT_LE(static_cast<double>(r.peak_rss_bytes - parent_rss), estimate + (32 << 20))
      << "peak " << r.peak_rss_bytes << ", parent " << parent_rss << ", estimate " << estimate;
}

}  // namespace
}  // namespace cellflow::jobs
#endif  // CELLFLOW_FUZZ_LONG
