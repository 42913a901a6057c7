// Shear-flow checkpoints: the format and its checks are described in
// shear_flow_checkpoint.h.
#include "physics/scenes/shear_flow/shear_flow_checkpoint.h"

#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <span>
#include <vector>

#include "physics/lb/fluid_state.h"

namespace cellflow::scenes::shear_flow_detail {

namespace {

constexpr std::uint64_t kMagic = 0x54504B43574C4643ULL;  // "CFLWCKPT" read as a little-endian word
constexpr int kHeaderWords = 20;
constexpr int kSampleWords = 16;

enum HeaderWord {
  kWordMagic,
  kWordVersion,
  kWordSpecHash,
  kWordNx,
  kWordNy,
  kWordNz,
  kWordPrecision,
  kWordStreaming,
  kWordVertices,
  kWordTets,
  kWordMeshHash,
  kWordStep,
  kWordSamples,
  kWordSnapshots,
  kWordTankVertices,
  kWordPopulationBytes,
  kWordWallBytes,
  kWordPayloadBytes,
  kWordPayloadChecksum,
  kWordHeaderChecksum,
};
static_assert(kWordMagic == 0 && kWordVersion == 1 && kWordHeaderChecksum + 1 == kHeaderWords,
              "the layout read_checkpoint_header and finish_checkpoint_file expect");

using Writer = CheckpointWriter;
using Reader = CheckpointReader;

// What the payload of these counts occupies; false on overflow.
bool payload_bytes(std::uint64_t vertices, std::uint64_t samples, std::uint64_t snapshots,
                   std::uint64_t tank_vertices, std::uint64_t population_bytes, std::uint64_t wall_bytes,
                   std::uint64_t& bytes) {
  const double words = 5.0 + 6.0 * static_cast<double>(vertices) + 2.0 * static_cast<double>(tank_vertices) +
                       static_cast<double>(samples) * (1 + kSampleWords) +
                       static_cast<double>(snapshots) * (2.0 + 3.0 * static_cast<double>(vertices));
  const double total = 8.0 * words + static_cast<double>(population_bytes) + static_cast<double>(wall_bytes);
  if (!(total < 9e18)) return false;
  bytes = 8 * (5 + 6 * vertices + 2 * tank_vertices + samples * (1 + kSampleWords) +
               snapshots * (2 + 3 * vertices)) +
          population_bytes + wall_bytes;
  return true;
}

void write_sample(Writer& w, const ShearFlowSample& s) {
  w.word(static_cast<std::uint64_t>(static_cast<std::int64_t>(s.index)));
  w.word(static_cast<std::uint64_t>(s.time_step));
  for (double v : {s.time_s, s.strain_units, s.taylor_deformation, s.inclination_deg, s.net_strain})
    w.real(v);
  for (double v : s.semi_axes_m) w.real(v);
  for (double v : s.centroid_m) w.real(v);
  for (double v : {s.volume_m3, s.elastic_energy_j, s.tank_treading_frequency_per_s}) w.real(v);
}

bool read_sample(Reader& r, ShearFlowSample& s) {
  std::uint64_t index = 0, step = 0;
  if (!r.word(index) || !r.word(step)) return false;
  s.index = static_cast<int>(static_cast<std::int64_t>(index));
  s.time_step = static_cast<std::int64_t>(step);
  bool ok = r.real(s.time_s) && r.real(s.strain_units) && r.real(s.taylor_deformation) &&
            r.real(s.inclination_deg) && r.real(s.net_strain);
  for (double& v : s.semi_axes_m) ok = ok && r.real(v);
  for (double& v : s.centroid_m) ok = ok && r.real(v);
  return ok && r.real(s.volume_m3) && r.real(s.elastic_energy_j) && r.real(s.tank_treading_frequency_per_s) &&
         index < (std::uint64_t{1} << 31);
}

Status refused(const std::string& why) {
  return checkpoint_refused(why);
}

std::string mismatch(const char* what, std::uint64_t file, std::uint64_t run) {
  return checkpoint_mismatch(what, file, run);
}

}  // namespace

std::uint64_t precision_word(const lb::Fluid& fluid, const coupling::ImmersedCells& cells) {
  return checkpoint_precision_word(
      fluid.params().precision == lb::Precision::kFloat,
      cells.size() > 0 && cells[0].elastic_precision == elastic::ForcePrecision::kFloat);
}

std::uint64_t mesh_hash(const mesh::TetMesh& mesh) {
  WordHash hash;
  for (double x : mesh.positions_m) hash.add(word_of(x));
  for (std::int32_t t : mesh.tets) hash.add(static_cast<std::uint32_t>(t));
  return hash.state;
}

StatusOr<std::uint64_t> write_checkpoint(const Run& run, const ShearFlowResult& result,
                                         const lb::Fluid& fluid, std::int64_t step, std::uint64_t spec_hash,
                                         const std::string& path) {
  const coupling::ImmersedCell& cell = run.cells[0];
  const std::size_t nv = run.mesh.num_vertices();
  const std::span<const std::byte> populations = lb::population_bytes(fluid);
  const std::span<const std::byte> walls = lb::wall_density_bytes(fluid);
  if (populations.size() % 8 != 0 || walls.size() % 8 != 0) {
    return Status(StatusCode::kInternal, "checkpoint: lattice storage is not a whole number of words");
  }
  std::array<std::uint64_t, kHeaderWords> header{};
  header[kWordMagic] = kMagic;
  header[kWordVersion] = kCheckpointFormatVersion;
  header[kWordSpecHash] = spec_hash;
  header[kWordNx] = static_cast<std::uint64_t>(fluid.nx());
  header[kWordNy] = static_cast<std::uint64_t>(fluid.ny());
  header[kWordNz] = static_cast<std::uint64_t>(fluid.nz());
  header[kWordPrecision] = precision_word(fluid, run.cells);
  header[kWordStreaming] = fluid.params().streaming == lb::Streaming::kAA ? 0 : 1;
  header[kWordVertices] = nv;
  header[kWordTets] = run.mesh.num_tets();
  header[kWordMeshHash] = mesh_hash(run.mesh);
  header[kWordStep] = static_cast<std::uint64_t>(step);
  header[kWordSamples] = result.samples.size();
  header[kWordSnapshots] = run.snapshots.size();
  header[kWordTankVertices] = run.tank_vertices.size();
  header[kWordPopulationBytes] = populations.size();
  header[kWordWallBytes] = walls.size();
  std::uint64_t payload = 0;
  if (!payload_bytes(nv, result.samples.size(), run.snapshots.size(), run.tank_vertices.size(),
                     populations.size(), walls.size(), payload)) {
    return Status(StatusCode::kInternal, "checkpoint: size overflow");
  }
  header[kWordPayloadBytes] = payload;

  const std::string temporary = path + ".tmp";
  std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
  if (!out) return Status(StatusCode::kInternal, "checkpoint: cannot create " + temporary);
  // The header goes first with a zero checksum and is rewritten at the end.
  out.write(reinterpret_cast<const char*>(header.data()), sizeof header);
  Writer w(out);
  w.real(run.last_energy_j);
  w.word(static_cast<std::uint64_t>(static_cast<std::int64_t>(run.snapshot_index)));
  const lb::FluidPhase phase = lb::fluid_phase(fluid);
  w.word(static_cast<std::uint64_t>(phase.time_step));
  w.word(phase.aa_swapped ? 1 : 0);
  w.word(static_cast<std::uint64_t>(phase.current));
  w.reals(cell.positions_lattice);
  w.reals(run.last_good_x_lb);
  w.reals(run.tank_angle);
  w.reals(run.tank_unwrapped);
  w.reals(run.tank_mean_angle);
  for (const ShearFlowSample& s : result.samples) write_sample(w, s);
  for (const StoredSnapshot& snap : run.snapshots) {
    w.word(static_cast<std::uint64_t>(static_cast<std::int64_t>(snap.index)));
    w.real(snap.time_s);
    w.reals(snap.x_lb);
  }
  w.block(populations);
  w.block(walls);
  return finish_checkpoint_file(out, header, kWordPayloadChecksum, w, payload, temporary, path);
}

StatusOr<std::int64_t> read_checkpoint(const std::string& path, std::uint64_t spec_hash,
                                       const Schedule& schedule, Run& run, ShearFlowResult& result,
                                       lb::Fluid& fluid) {
  std::array<std::uint64_t, kHeaderWords> header{};
  std::ifstream in;
  const StatusOr<std::uint64_t> file_size =
      read_checkpoint_header(path, in, header, kMagic, kCheckpointFormatVersion, "shear-flow");
  if (!file_size.ok()) return file_size.status();
  const std::uint64_t file_bytes = *file_size;
  if (header[kWordSpecHash] != spec_hash) return refused("written for another job spec (spec hash differs)");

  const std::size_t nv = run.mesh.num_vertices();
  const std::span<std::byte> populations = lb::mutable_population_bytes(fluid);
  const std::span<std::byte> walls = lb::mutable_wall_density_bytes(fluid);
  const struct {
    HeaderWord word;
    const char* what;
    std::uint64_t expected;
  } dimensions[] = {
      {kWordNx, "lattice nx", static_cast<std::uint64_t>(fluid.nx())},
      {kWordNy, "lattice ny", static_cast<std::uint64_t>(fluid.ny())},
      {kWordNz, "lattice nz", static_cast<std::uint64_t>(fluid.nz())},
      {kWordPrecision, "precision (bit 0: float populations, bit 1: float elastic forces)",
       precision_word(fluid, run.cells)},
      {kWordStreaming, "streaming (0 AA)", fluid.params().streaming == lb::Streaming::kAA ? 0u : 1u},
      {kWordVertices, "vertex count", nv},
      {kWordTets, "tet count", run.mesh.num_tets()},
      {kWordMeshHash, "reference mesh hash", mesh_hash(run.mesh)},
      {kWordTankVertices, "tank-treading vertex count", run.tank_vertices.size()},
      {kWordPopulationBytes, "population bytes", populations.size()},
      {kWordWallBytes, "wall-density bytes", walls.size()},
  };
  for (const auto& d : dimensions) {
    if (header[d.word] != d.expected) return refused(mismatch(d.what, header[d.word], d.expected));
  }
  // Checkpoints are written at sample steps within the run's limit.
  const std::uint64_t step_word = header[kWordStep];
  if (step_word == 0 || step_word > static_cast<std::uint64_t>(schedule.max_steps) ||
      step_word % static_cast<std::uint64_t>(schedule.sample_steps) != 0) {
    return refused("time step " + std::to_string(step_word) + " is not a sample step in (0, " +
                   std::to_string(schedule.max_steps) + "]");
  }
  const auto step = static_cast<std::int64_t>(step_word);
  const std::uint64_t samples = header[kWordSamples];
  const std::uint64_t max_samples = static_cast<std::uint64_t>(step / schedule.sample_steps) + 1;
  if (samples == 0 || samples > max_samples) {
    return refused(std::to_string(samples) + " samples, at most " + std::to_string(max_samples) +
                   " by step " + std::to_string(step));
  }
  const std::uint64_t snapshots = header[kWordSnapshots];
  const std::uint64_t max_snapshots =
      schedule.snapshot_steps > 0 ? static_cast<std::uint64_t>(step / schedule.snapshot_steps) + 1 : 0;
  if (snapshots > max_snapshots) {
    return refused(std::to_string(snapshots) + " snapshots, at most " + std::to_string(max_snapshots) +
                   " by step " + std::to_string(step));
  }
  std::uint64_t payload = 0;
  if (!payload_bytes(nv, samples, snapshots, run.tank_vertices.size(), populations.size(), walls.size(),
                     payload) ||
      header[kWordPayloadBytes] != payload) {
    return refused("payload size " + std::to_string(header[kWordPayloadBytes]) +
                   " disagrees with its counts");
  }
  if (file_bytes != sizeof header + payload) {
    return refused("the file has " + std::to_string(file_bytes) + " bytes, its header says " +
                   std::to_string(sizeof header + payload) + " (truncated or padded)");
  }

  // Everything below the populations lands in temporaries first.
  Reader r(in);
  double last_energy = 0.0;
  std::uint64_t snapshot_index = 0, fluid_step = 0, swapped = 0, current = 0;
  std::vector<double> positions, last_good, tank_angle, tank_unwrapped, tank_mean;
  const std::size_t tv = run.tank_vertices.size();
  bool ok = r.real(last_energy) && r.word(snapshot_index) && r.word(fluid_step) && r.word(swapped) &&
            r.word(current) && r.reals(positions, 3 * nv) && r.reals(last_good, 3 * nv) &&
            r.reals(tank_angle, tv) && r.reals(tank_unwrapped, tv) && r.reals(tank_mean, samples);
  std::vector<ShearFlowSample> stored(ok ? samples : 0);
  for (ShearFlowSample& s : stored) ok = ok && read_sample(r, s);
  std::vector<StoredSnapshot> stored_snapshots(ok ? snapshots : 0);
  for (StoredSnapshot& snap : stored_snapshots) {
    std::uint64_t index = 0;
    ok = ok && r.word(index) && r.real(snap.time_s) && r.reals(snap.x_lb, 3 * nv);
    snap.index = static_cast<int>(std::min<std::uint64_t>(index, 1u << 30));
  }
  ok = ok && r.block(populations) && r.block(walls);
  if (!ok) return refused("truncated payload");
  if (r.checksum() != header[kWordPayloadChecksum]) return refused("payload checksum mismatch (corrupted)");

  // Consistency of what the checksum covered.
  for (std::size_t i = 0; i < stored.size(); ++i) {
    const ShearFlowSample& s = stored[i];
    if (s.index != static_cast<int>(i) || s.time_step < 0 || s.time_step > step ||
        (i > 0 && s.time_step <= stored[i - 1].time_step)) {
      return refused("sample " + std::to_string(i) + " out of order");
    }
  }
  if (stored.back().time_step != step) return refused("the last sample is not at the checkpoint's step");
  if (fluid_step != step_word || swapped > 1 || current > 1)
    return refused("fluid phase disagrees with the step");
  if (snapshot_index > max_snapshots + 1) return refused("snapshot index out of range");
  if (!all_finite(positions) || !all_finite(last_good) || !all_finite(tank_angle) ||
      !all_finite(tank_unwrapped) || !all_finite(tank_mean)) {
    return refused("non-finite positions or angles");
  }
  for (const StoredSnapshot& snap : stored_snapshots) {
    if (snap.index < 0 || static_cast<std::uint64_t>(snap.index) > snapshot_index ||
        !std::isfinite(snap.time_s))
      return refused("snapshot out of range");
  }
  lb::FluidPhase phase;
  phase.time_step = step;
  phase.aa_swapped = swapped == 1;
  phase.current = static_cast<int>(current);
  if (Status s = lb::set_fluid_phase(fluid, phase); !s.ok()) return refused(s.message());

  run.cells[0].positions_lattice = std::move(positions);
  run.last_good_x_lb = std::move(last_good);
  run.tank_angle = std::move(tank_angle);
  run.tank_unwrapped = std::move(tank_unwrapped);
  run.tank_mean_angle = std::move(tank_mean);
  run.last_energy_j = last_energy;
  run.snapshot_index = static_cast<int>(snapshot_index);
  run.snapshots = std::move(stored_snapshots);
  result.samples = std::move(stored);
  return step;
}

}  // namespace cellflow::scenes::shear_flow_detail
