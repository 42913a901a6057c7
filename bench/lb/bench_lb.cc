// Lattice Boltzmann collide-stream throughput against the memory-bandwidth
// roofline of this machine, measured in the same run.
//
// BM_LbStep/n/precision/scheme/coupled/threads: an n^3 D3Q19 lattice with
// moving walls in y (plane Couette), TRT + Guo forcing; precision 0 = double,
// 1 = float; scheme 0 = AA pattern (in place), 1 = two arrays (push);
// coupled 1 = with the IBM force field read and the velocity field written by
// the fused kernel. One iteration = 2 steps (both AA phases).
//
// Beside the timed steps, every iteration (at most every 20 ms of lattice CPU
// time) measures the memory bandwidth with the same thread count (one untimed
// pass over 2 x 256 MiB; the median is used):
//   copy_GBps:   a[i] = s b[i]  (STREAM "scale": 16 bytes per element counted;
//                the write-allocate read of a is not counted, as in STREAM)
//   update_GBps: a[i] = s a[i]  (in place: 16 bytes per element, no write-allocate)
// Bytes per lattice update (counted like STREAM): 2 x 19 x sizeof(T), plus
// 6 x sizeof(T) when coupled (3 force reads, 3 velocity writes).
// The ceiling is the bandwidth of the memory pattern the scheme really has:
//   AA pattern (in place): it reads and writes the same lines, 2 x 19 x sizeof(T)
//     really moved and no write-allocate, like update: ceiling = update_GBps.
//   two arrays (push): it writes lines it has not read and pays the
//     write-allocate, as copy does (both counted without it): ceiling = copy_GBps.
//   roofline_MLUPS = ceiling_GBps / bytes_per_update, frac_roof = MLUPS / roofline_MLUPS
// (Against copy_GBps an AA update looked faster than the hardware: copy moves
// 24 bytes per element and is counted as 16, so its figure understates the
// in-place bandwidth; one run printed frac_roof = 1.04.) frac_copy_roof is
// MLUPS against copy_GBps, the earlier figure, for comparison.
//
// The machine is shared: run with --benchmark_repetitions=5
// --benchmark_report_aggregates_only=true and quote the medians.
// On a loaded machine the wall-time figures also measure how much of a core
// the process got; the *_cpu counters divide by the CPU time of the process
// (per thread: CPU seconds / threads) for the lattice steps and for the
// bandwidth passes alike, so their ratio frac_roof_cpu does not depend on
// the time slices the scheduler gave (it still depends on the memory traffic
// of the neighbours). On an idle machine both agree.
//
// BM_LbStepRowsInCache: a 128 x 16 x 4 lattice (1.2 MB in double, inside the
// 2 MB L2 of one core) with the rows of the 128^3 case: its MLUPS_cpu is the
// ceiling of the arithmetic and the row set-up, without memory traffic.
// BM_AaEvenPattern: the memory pattern of an AA even step without its
// arithmetic (19 arrays of n^3, every node's pairs swapped in place and
// scaled): pattern_GBps against update_GBps says whether 19 read-modify-write
// streams cost bandwidth against one.
#include <benchmark/benchmark.h>
#include <omp.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "physics/lb/aligned_array.h"
#include "physics/lb/fluid.h"

namespace cellflow::lb {
namespace {

constexpr std::size_t kStreamElements = std::size_t{32} << 20;  // 256 MiB of doubles per array

// Two arrays far larger than the last-level cache, first touched by the
// threads that stream them.
struct StreamArrays {
  AlignedArray<double> a{kStreamElements}, b{kStreamElements};
};

StreamArrays& stream_arrays() {
  static StreamArrays arrays;
  return arrays;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// CPU seconds of the whole process (all threads).
double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

struct Bandwidth {
  double copy, update;          // GB/s per wall second
  double copy_cpu, update_cpu;  // GB/s per CPU second of each thread
};

// One pass of each bandwidth kernel.
Bandwidth bandwidth_sample(int threads) {
  double* pa = stream_arrays().a.data();
  double* pb = stream_arrays().b.data();
  const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(kStreamElements);
  volatile double scale_source = 1.0;
  const double s = scale_source;
  const double bytes = 2.0 * sizeof(double) * static_cast<double>(n);
  Bandwidth bw{};
  auto t0 = std::chrono::steady_clock::now();
  double c0 = process_cpu_seconds();
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::ptrdiff_t i = 0; i < n; ++i) pa[i] = s * pb[i];
  bw.copy = bytes / seconds_since(t0) / 1e9;
  bw.copy_cpu = bytes * threads / (process_cpu_seconds() - c0) / 1e9;
  t0 = std::chrono::steady_clock::now();
  c0 = process_cpu_seconds();
#pragma omp parallel for schedule(static) num_threads(threads)
  for (std::ptrdiff_t i = 0; i < n; ++i) pa[i] = s * pa[i];
  bw.update = bytes / seconds_since(t0) / 1e9;
  bw.update_cpu = bytes * threads / (process_cpu_seconds() - c0) / 1e9;
  benchmark::DoNotOptimize(pa[n / 2]);
  return bw;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

// with_phases: a phase field with a sphere of radius n/4 in phase 1 (tau
// 0.525, lambda = 0.083 of tau 0.8), the viscosity-contrast kernel.
// rows_in_cache: a 128 x 16 x 4 lattice instead of n^3.
void lb_step(benchmark::State& state, bool with_phases, bool rows_in_cache = false) {
  const int n = static_cast<int>(state.range(0));
  const bool single = state.range(1) == 1;
  const bool two_array = state.range(2) == 1;
  const bool coupled = state.range(3) == 1;
  const int threads = static_cast<int>(state.range(4));
  FluidParams p;
  p.nx = p.ny = p.nz = n;
  if (rows_in_cache) {
    p.ny = 16;
    p.nz = 4;
  }
  p.tau = 0.8;
  p.lower_wall_velocity = {-0.05, 0.0, 0.0};
  p.upper_wall_velocity = {0.05, 0.0, 0.0};
  p.force_field = coupled;
  p.velocity_field = coupled;
  p.precision = single ? Precision::kFloat : Precision::kDouble;
  p.streaming = two_array ? Streaming::kTwoArray : Streaming::kAA;
  p.threads = threads;
  if (with_phases) p.phase_taus = {0.525};
  StatusOr<Fluid> made = make_fluid(p);
  if (!made.ok()) {
    state.SkipWithError(made.status().message().c_str());
    return;
  }
  Fluid fluid = std::move(made).value();
  if (with_phases) {
    std::vector<std::uint8_t> phases(fluid.num_nodes(), 0);
    const double c = 0.5 * n, r2 = 0.0625 * n * n;
    for (int k = 0; k < n; ++k)
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          const double x = i + 0.5 - c, y = j + 0.5 - c, z = k + 0.5 - c;
          if (x * x + y * y + z * z < r2) phases[fluid.node(i, j, k)] = 1;
        }
    if (Status s = set_phases(fluid, phases); !s.ok()) {
      state.SkipWithError(s.message().c_str());
      return;
    }
  }
  collide_stream(fluid);  // touch every page once before timing
  collide_stream(fluid);
  bandwidth_sample(threads);
  // The machine is shared: each iteration samples the bandwidth right before
  // its two lattice steps (untimed), so roofline and MLUPS see the same load.
  // A small lattice takes far less time than one bandwidth pass: samples
  // are taken at least every 20 ms of lattice CPU time, not every iteration.
  std::vector<double> copy, update, copy_cpu, update_cpu;
  double lb_cpu_seconds = 0.0, sampled_at = -1.0, first_cpu_seconds = 0.0;
  for (auto _ : state) {
    if (sampled_at < 0.0 || lb_cpu_seconds - sampled_at >= 0.02) {
      state.PauseTiming();
      const Bandwidth bw = bandwidth_sample(threads);
      copy.push_back(bw.copy);
      update.push_back(bw.update);
      copy_cpu.push_back(bw.copy_cpu);
      update_cpu.push_back(bw.update_cpu);
      sampled_at = lb_cpu_seconds;
      state.ResumeTiming();
    }
    const double c0 = process_cpu_seconds();
    collide_stream(fluid);
    const double c1 = process_cpu_seconds();
    collide_stream(fluid);
    lb_cpu_seconds += process_cpu_seconds() - c0;
    first_cpu_seconds += c1 - c0;
  }
  const double copy_gbps = median(copy), update_gbps = median(update);
  const double updates =
      2.0 * static_cast<double>(fluid.num_nodes()) * static_cast<double>(state.iterations());
  const double value = single ? sizeof(float) : sizeof(double);
  const double bytes_per_update = (2.0 * kQ + (coupled ? 6.0 : 0.0)) * value;
  const double ceiling_gbps = two_array ? copy_gbps : update_gbps;
  const double roofline_mlups = ceiling_gbps * 1e3 / bytes_per_update;
  state.counters["MLUPS"] = benchmark::Counter(updates / 1e6, benchmark::Counter::kIsRate);
  state.counters["copy_GBps"] = copy_gbps;
  state.counters["update_GBps"] = update_gbps;
  state.counters["ceiling_GBps"] = ceiling_gbps;
  state.counters["bytes_per_update"] = bytes_per_update;
  state.counters["roofline_MLUPS"] = roofline_mlups;
  // MLUPS / roofline: a rate counter divided by the roofline.
  state.counters["frac_roof"] =
      benchmark::Counter(updates / 1e6 / roofline_mlups, benchmark::Counter::kIsRate);
  state.counters["frac_copy_roof"] =
      benchmark::Counter(updates / 1e6 / (copy_gbps * 1e3 / bytes_per_update), benchmark::Counter::kIsRate);
  // The same per CPU second of each thread (see the header).
  const double mlups_cpu = updates / 1e6 / (lb_cpu_seconds / threads);
  const double ceiling_cpu = two_array ? median(copy_cpu) : median(update_cpu);
  state.counters["MLUPS_cpu"] = mlups_cpu;
  state.counters["update_GBps_cpu"] = median(update_cpu);
  state.counters["frac_roof_cpu"] = mlups_cpu / (ceiling_cpu * 1e3 / bytes_per_update);
  if (!two_array) {
    // Each iteration is an even step (local) and an odd step (streaming).
    const double per_step = updates / 2e6 * threads;
    state.counters["even_MLUPS_cpu"] = per_step / first_cpu_seconds;
    state.counters["odd_MLUPS_cpu"] = per_step / (lb_cpu_seconds - first_cpu_seconds);
  }
  state.SetLabel(simd_name(best_simd()));
}

void BM_LbStep(benchmark::State& state) {
  lb_step(state, false);
}

void BM_LbStepRowsInCache(benchmark::State& state) {
  lb_step(state, false, true);
}

// One AA even step's memory traffic without its arithmetic: in every node the
// pairs (q, q + 9) are swapped and scaled in place, the rest population scaled.
template <class T>
void BM_AaEvenPattern(benchmark::State& state) {
  const std::size_t n = static_cast<std::size_t>(state.range(0));
  const int threads = static_cast<int>(state.range(1));
  const std::size_t nodes = n * n * n;
  // The direction stride of the lattice (fluid_internal.h): one cache line
  // more than a multiple of 16 values, so that the 19 streams do not alias in
  // the low address bits (with a stride of 16 MiB they measured 0.5 of update).
  const std::size_t stride = (nodes + 15) / 16 * 16 + 16;
  AlignedArray<T> pops(kQ * stride);
  T* const base = pops.data();
  volatile T scale_source = 1;
  const T s = scale_source;
  const auto pass = [&] {
  // Rows of n nodes, split among the threads like the lattice rows.
#pragma omp parallel for schedule(static) num_threads(threads)
    for (std::ptrdiff_t r = 0; r < static_cast<std::ptrdiff_t>(n * n); ++r) {
      T* p[kQ];
      for (int q = 0; q < kQ; ++q) p[q] = base + q * stride + static_cast<std::size_t>(r) * n;
#pragma omp simd
      for (std::size_t x = 0; x < n; ++x) {
        p[0][x] = s * p[0][x];
        for (int q = 1; q <= kPairs; ++q) {
          const T a = p[q][x], b = p[q + kPairs][x];
          p[q][x] = s * b;
          p[q + kPairs][x] = s * a;
        }
      }
    }
  };
  pass();  // first touch by the threads that stream the arrays
  bandwidth_sample(threads);
  std::vector<double> update, update_cpu;
  double cpu_seconds = 0.0;
  for (auto _ : state) {  // one pass takes about as long as a bandwidth sample
    state.PauseTiming();
    const Bandwidth bw = bandwidth_sample(threads);
    update.push_back(bw.update);
    update_cpu.push_back(bw.update_cpu);
    state.ResumeTiming();
    const double c0 = process_cpu_seconds();
    pass();
    cpu_seconds += process_cpu_seconds() - c0;
  }
  benchmark::DoNotOptimize(base[nodes / 2]);
  const double bytes =
      2.0 * kQ * sizeof(T) * static_cast<double>(nodes) * static_cast<double>(state.iterations());
  state.counters["pattern_GBps"] = benchmark::Counter(bytes / 1e9, benchmark::Counter::kIsRate);
  state.counters["update_GBps"] = median(update);
  state.counters["frac_update"] =
      benchmark::Counter(bytes / 1e9 / median(update), benchmark::Counter::kIsRate);
  const double pattern_cpu = bytes / 1e9 / (cpu_seconds / threads);
  state.counters["pattern_GBps_cpu"] = pattern_cpu;
  state.counters["update_GBps_cpu"] = median(update_cpu);
  state.counters["frac_update_cpu"] = pattern_cpu / median(update_cpu);
}

// The same with the per-node phase field (viscosity contrast).
void BM_LbStepPhases(benchmark::State& state) {
  lb_step(state, true);
}

// n, precision, scheme, coupled, threads
BENCHMARK(BM_LbStep)
    ->ArgNames({"n", "float", "two_array", "coupled", "threads"})
    ->ArgsProduct({{128}, {0, 1}, {0, 1}, {0, 1}, {1, 2}})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

// A lattice that fits in the last-level cache: the compute ceiling.
BENCHMARK(BM_LbStep)
    ->ArgNames({"n", "float", "two_array", "coupled", "threads"})
    ->ArgsProduct({{32}, {0, 1}, {0}, {0}, {1}})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

// The rows of the 128^3 lattice in a lattice inside L2.
BENCHMARK(BM_LbStepRowsInCache)
    ->ArgNames({"n", "float", "two_array", "coupled", "threads"})
    ->ArgsProduct({{128}, {0, 1}, {0}, {0}, {1}})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

// n, threads
BENCHMARK(BM_AaEvenPattern<double>)->ArgNames({"n", "threads"})->ArgsProduct({{128}, {1, 2}})->UseRealTime();
BENCHMARK(BM_AaEvenPattern<float>)->ArgNames({"n", "threads"})->ArgsProduct({{128}, {1, 2}})->UseRealTime();

// Viscosity contrast: the phase-field kernel beside BM_LbStep's.
BENCHMARK(BM_LbStepPhases)
    ->ArgNames({"n", "float", "two_array", "coupled", "threads"})
    ->ArgsProduct({{128}, {0, 1}, {0}, {1}, {1}})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace cellflow::lb

BENCHMARK_MAIN();
