// Suspension checkpoints: the format and its checks are described in
// suspension_checkpoint.h; the word layer is shared with the single cell's
// (physics/scenes/shear_flow/checkpoint_io.h).
#include "physics/scenes/suspension/suspension_checkpoint.h"

#include <array>
#include <fstream>

#include "physics/lb/fluid_state.h"
#include "physics/scenes/shear_flow/checkpoint_io.h"
#include "physics/scenes/shear_flow/shear_flow_checkpoint.h"

namespace cellflow::scenes::suspension_detail {

namespace {

using shear_flow_detail::all_finite;
using shear_flow_detail::CheckpointReader;
using shear_flow_detail::CheckpointWriter;
using shear_flow_detail::finish_checkpoint_file;
using shear_flow_detail::header_checksum;
using shear_flow_detail::read_checkpoint_header;
using shear_flow_detail::word_of;
using shear_flow_detail::WordHash;

constexpr std::uint64_t kMagic = 0x50535553574C4643ULL;  // "CFLWSUSP" read as a little-endian word
constexpr int kHeaderWords = 21;
constexpr std::uint64_t kLoopWords = 7;         // snapshot index ... marking updates
constexpr std::uint64_t kSampleWords = 12;      // per sample, besides its cells
constexpr std::uint64_t kCellSampleWords = 10;  // per cell of a sample

enum HeaderWord {
  kWordMagic,
  kWordVersion,
  kWordSpecHash,
  kWordNx,
  kWordNy,
  kWordNz,
  kWordPrecision,
  kWordStreaming,
  kWordCells,
  kWordVertices,
  kWordCellsHash,
  kWordStep,
  kWordSamples,
  kWordSnapshots,
  kWordContactVertices,
  kWordMarking,
  kWordPopulationBytes,
  kWordWallBytes,
  kWordPayloadBytes,
  kWordPayloadChecksum,
  kWordHeaderChecksum,
};
static_assert(kWordMagic == 0 && kWordVersion == 1 && kWordHeaderChecksum + 1 == kHeaderWords,
              "the layout read_checkpoint_header and finish_checkpoint_file expect");

using Header = std::array<std::uint64_t, kHeaderWords>;

std::size_t total_vertices(const coupling::ImmersedCells& cells) {
  std::size_t n = 0;
  for (const coupling::ImmersedCell& cell : cells.cells) n += cell.positions_lattice.size() / 3;
  return n;
}

// What the payload of these counts occupies; false on overflow (checked in
// double first, so that no product below wraps).
bool payload_bytes(std::uint64_t cells, std::uint64_t vertices, std::uint64_t samples,
                   std::uint64_t snapshots, std::uint64_t contact_vertices, std::uint64_t population_bytes,
                   std::uint64_t wall_bytes, std::uint64_t& bytes) {
  const double c = static_cast<double>(cells), v = static_cast<double>(vertices);
  const double words = static_cast<double>(kLoopWords) + 3.0 * v +
                       3.0 * static_cast<double>(contact_vertices) +
                       static_cast<double>(samples) * (kSampleWords + kCellSampleWords * c) +
                       static_cast<double>(snapshots) * (2.0 + 3.0 * v);
  const double total = 8.0 * words + static_cast<double>(population_bytes) + static_cast<double>(wall_bytes);
  if (!(total < 9e18)) return false;
  bytes = 8 * (kLoopWords + 3 * vertices + 3 * contact_vertices +
               samples * (kSampleWords + kCellSampleWords * cells) + snapshots * (2 + 3 * vertices)) +
          population_bytes + wall_bytes;
  return true;
}

std::uint64_t signed_word(std::int64_t v) {
  return static_cast<std::uint64_t>(v);
}

void write_sample(CheckpointWriter& w, const SuspensionSample& s) {
  w.word(signed_word(s.index));
  w.word(signed_word(s.time_step));
  for (double v :
       {s.time_s, s.strain_units, s.mean_taylor_deformation, s.mean_inclination_deg, s.relative_viscosity})
    w.real(v);
  w.word(signed_word(s.contact_pairs));
  for (double v : {s.average_taylor_deformation, s.average_taylor_deformation_error,
                   s.average_relative_viscosity, s.average_relative_viscosity_error})
    w.real(v);
  for (const SuspendedCellSample& c : s.cells) {
    for (double v : {c.taylor_deformation, c.inclination_deg, c.net_strain}) w.real(v);
    for (double v : c.semi_axes_m) w.real(v);
    for (double v : c.centroid_m) w.real(v);
    w.real(c.volume_m3);
  }
}

bool read_sample(CheckpointReader& r, SuspensionSample& s, std::size_t cells) {
  std::uint64_t index = 0, step = 0, pairs = 0;
  bool ok = r.word(index) && r.word(step) && r.real(s.time_s) && r.real(s.strain_units) &&
            r.real(s.mean_taylor_deformation) && r.real(s.mean_inclination_deg) &&
            r.real(s.relative_viscosity) && r.word(pairs) && r.real(s.average_taylor_deformation) &&
            r.real(s.average_taylor_deformation_error) && r.real(s.average_relative_viscosity) &&
            r.real(s.average_relative_viscosity_error);
  s.index = static_cast<int>(std::min<std::uint64_t>(index, std::uint64_t{1} << 31));
  s.time_step = static_cast<std::int64_t>(step);
  s.contact_pairs = static_cast<int>(std::min<std::uint64_t>(pairs, std::uint64_t{1} << 31));
  s.cells.resize(ok ? cells : 0);
  for (SuspendedCellSample& c : s.cells) {
    ok = ok && r.real(c.taylor_deformation) && r.real(c.inclination_deg) && r.real(c.net_strain);
    for (double& v : c.semi_axes_m) ok = ok && r.real(v);
    for (double& v : c.centroid_m) ok = ok && r.real(v);
    ok = ok && r.real(c.volume_m3);
  }
  return ok && index < (std::uint64_t{1} << 31) && pairs < (std::uint64_t{1} << 31);
}

Status refused(const std::string& why) {
  return shear_flow_detail::checkpoint_refused(why);
}

}  // namespace

std::uint64_t cells_hash(const coupling::ImmersedCells& cells, std::span<const int> cell_kind) {
  WordHash hash;
  for (std::size_t c = 0; c < cells.size(); ++c) {
    hash.add(c < cell_kind.size() ? static_cast<std::uint64_t>(static_cast<std::int64_t>(cell_kind[c])) : 0);
    hash.add(shear_flow_detail::mesh_hash(*cells[c].mesh));
    hash.add(word_of(cells[c].marker_scale));
  }
  return hash.state;
}

StatusOr<std::uint64_t> write_checkpoint(const CheckpointLayout& layout, const coupling::ImmersedCells& cells,
                                         const LoopState& loop, std::span<const SuspensionSample> samples,
                                         const lb::Fluid& fluid, std::int64_t step, const std::string& path) {
  const std::size_t nv = total_vertices(cells);
  const std::span<const std::byte> populations = lb::population_bytes(fluid);
  const std::span<const std::byte> walls = lb::wall_density_bytes(fluid);
  if (populations.size() % 8 != 0 || walls.size() % 8 != 0) {
    return Status(StatusCode::kInternal, "checkpoint: lattice storage is not a whole number of words");
  }
  if (loop.contact_built_at.size() != 3 * layout.contact_vertices) {
    return Status(StatusCode::kInternal,
                  "checkpoint: the contact list's build positions disagree with its size");
  }
  for (const SuspensionSample& s : samples) {
    if (s.cells.size() != cells.size())
      return Status(StatusCode::kInternal, "checkpoint: a sample without every cell");
  }
  for (const StoredFrame& f : loop.snapshots) {
    if (f.x_lb.size() != 3 * nv)
      return Status(StatusCode::kInternal, "checkpoint: a snapshot without every cell");
  }
  Header header{};
  header[kWordMagic] = kMagic;
  header[kWordVersion] = kSuspensionCheckpointFormatVersion;
  header[kWordSpecHash] = layout.spec_hash;
  header[kWordNx] = static_cast<std::uint64_t>(fluid.nx());
  header[kWordNy] = static_cast<std::uint64_t>(fluid.ny());
  header[kWordNz] = static_cast<std::uint64_t>(fluid.nz());
  header[kWordPrecision] = shear_flow_detail::precision_word(fluid, cells);
  header[kWordStreaming] = fluid.params().streaming == lb::Streaming::kAA ? 0 : 1;
  header[kWordCells] = cells.size();
  header[kWordVertices] = nv;
  header[kWordCellsHash] = layout.cells_hash;
  header[kWordStep] = signed_word(step);
  header[kWordSamples] = samples.size();
  header[kWordSnapshots] = loop.snapshots.size();
  header[kWordContactVertices] = layout.contact_vertices;
  header[kWordMarking] = layout.marking ? 1 : 0;
  header[kWordPopulationBytes] = populations.size();
  header[kWordWallBytes] = walls.size();
  std::uint64_t payload = 0;
  if (!payload_bytes(cells.size(), nv, samples.size(), loop.snapshots.size(), layout.contact_vertices,
                     populations.size(), walls.size(), payload)) {
    return Status(StatusCode::kInternal, "checkpoint: size overflow");
  }
  header[kWordPayloadBytes] = payload;

  const std::string temporary = path + ".tmp";
  std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
  if (!out) return Status(StatusCode::kInternal, "checkpoint: cannot create " + temporary);
  // The header goes first with a zero checksum and is rewritten at the end.
  out.write(reinterpret_cast<const char*>(header.data()), sizeof header);
  CheckpointWriter w(out);
  w.word(signed_word(loop.snapshot_index));
  w.word(signed_word(loop.last_contact_pairs));
  const lb::FluidPhase phase = lb::fluid_phase(fluid);
  w.word(signed_word(phase.time_step));
  w.word(phase.aa_swapped ? 1 : 0);
  w.word(signed_word(phase.current));
  w.word(signed_word(loop.contact_list_builds));
  w.word(signed_word(loop.marking_updates));
  for (const coupling::ImmersedCell& cell : cells.cells) w.reals(cell.positions_lattice);
  w.reals(loop.contact_built_at);
  for (const SuspensionSample& s : samples) write_sample(w, s);
  for (const StoredFrame& f : loop.snapshots) {
    w.word(signed_word(f.index));
    w.real(f.time_s);
    w.reals(f.x_lb);
  }
  w.block(populations);
  w.block(walls);
  return finish_checkpoint_file(out, header, kWordPayloadChecksum, w, payload, temporary, path);
}

StatusOr<RestoredState> read_checkpoint(const std::string& path, const CheckpointLayout& layout,
                                        const coupling::ImmersedCells& cells, lb::Fluid& fluid) {
  Header header{};
  std::ifstream in;
  const StatusOr<std::uint64_t> file_size =
      read_checkpoint_header(path, in, header, kMagic, kSuspensionCheckpointFormatVersion, "suspension");
  if (!file_size.ok()) return file_size.status();
  const std::uint64_t file_bytes = *file_size;
  if (header[kWordSpecHash] != layout.spec_hash)
    return refused("written for another job spec (spec hash differs)");

  const std::size_t nv = total_vertices(cells);
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
       shear_flow_detail::precision_word(fluid, cells)},
      {kWordStreaming, "streaming (0 AA)", fluid.params().streaming == lb::Streaming::kAA ? 0u : 1u},
      {kWordCells, "cell count", cells.size()},
      {kWordVertices, "vertex count", nv},
      {kWordCellsHash, "cells hash (kinds, meshes, marker scales)", layout.cells_hash},
      {kWordContactVertices, "contact vertex count", layout.contact_vertices},
      {kWordMarking, "marking (1 viscosity contrast)", layout.marking ? 1u : 0u},
      {kWordPopulationBytes, "population bytes", populations.size()},
      {kWordWallBytes, "wall-density bytes", walls.size()},
  };
  for (const auto& d : dimensions) {
    if (header[d.word] != d.expected)
      return refused(shear_flow_detail::checkpoint_mismatch(d.what, header[d.word], d.expected));
  }
  // Checkpoints are written at sample steps (marking steps too with a contrast) within the run's limit.
  const std::uint64_t step_word = header[kWordStep];
  const auto sample_steps = static_cast<std::uint64_t>(layout.sample_steps);
  const auto marking_every = static_cast<std::uint64_t>(layout.marking ? layout.marking_every : 1);
  if (step_word == 0 || step_word > static_cast<std::uint64_t>(layout.max_steps) ||
      step_word % sample_steps != 0 || step_word % marking_every != 0) {
    return refused("time step " + std::to_string(step_word) + " is not a sample" +
                   (layout.marking ? " and marking" : "") + " step in (0, " +
                   std::to_string(layout.max_steps) + "]");
  }
  const auto step = static_cast<std::int64_t>(step_word);
  const std::uint64_t samples = header[kWordSamples];
  const std::uint64_t max_samples = step_word / sample_steps + 1;
  if (samples == 0 || samples > max_samples) {
    return refused(std::to_string(samples) + " samples, at most " + std::to_string(max_samples) +
                   " by step " + std::to_string(step));
  }
  const std::uint64_t snapshots = header[kWordSnapshots];
  const std::uint64_t max_snapshots =
      layout.snapshot_steps > 0 ? step_word / static_cast<std::uint64_t>(layout.snapshot_steps) + 1 : 0;
  if (snapshots > max_snapshots) {
    return refused(std::to_string(snapshots) + " snapshots, at most " + std::to_string(max_snapshots) +
                   " by step " + std::to_string(step));
  }
  std::uint64_t payload = 0;
  if (!payload_bytes(cells.size(), nv, samples, snapshots, layout.contact_vertices, populations.size(),
                     walls.size(), payload) ||
      header[kWordPayloadBytes] != payload) {
    return refused("payload size " + std::to_string(header[kWordPayloadBytes]) +
                   " disagrees with its counts");
  }
  if (file_bytes != sizeof header + payload) {
    return refused("the file has " + std::to_string(file_bytes) + " bytes, its header says " +
                   std::to_string(sizeof header + payload) + " (truncated or padded)");
  }

  // Everything below the populations lands in temporaries first; every
  // count was bounded by the file size above.
  CheckpointReader r(in);
  RestoredState restored;
  restored.step = step;
  LoopState& loop = restored.loop;
  std::uint64_t snapshot_index = 0, contact_pairs = 0, fluid_step = 0, swapped = 0, current = 0, builds = 0,
                updates = 0;
  bool ok = r.word(snapshot_index) && r.word(contact_pairs) && r.word(fluid_step) && r.word(swapped) &&
            r.word(current) && r.word(builds) && r.word(updates);
  restored.positions.resize(ok ? cells.size() : 0);
  for (std::size_t c = 0; c < restored.positions.size(); ++c)
    ok = ok && r.reals(restored.positions[c], cells[c].positions_lattice.size());
  ok = ok && r.reals(loop.contact_built_at, 3 * layout.contact_vertices);
  restored.samples.resize(ok ? samples : 0);
  for (SuspensionSample& s : restored.samples) ok = ok && read_sample(r, s, cells.size());
  loop.snapshots.resize(ok ? snapshots : 0);
  for (StoredFrame& f : loop.snapshots) {
    std::uint64_t index = 0;
    ok = ok && r.word(index) && r.real(f.time_s) && r.reals(f.x_lb, 3 * nv);
    f.index = static_cast<int>(std::min<std::uint64_t>(index, std::uint64_t{1} << 30));
  }
  ok = ok && r.block(populations) && r.block(walls);
  if (!ok) return refused("truncated payload");
  if (r.checksum() != header[kWordPayloadChecksum]) return refused("payload checksum mismatch (corrupted)");

  // Consistency of what the checksum covered.
  const std::vector<SuspensionSample>& stored = restored.samples;
  for (std::size_t i = 0; i < stored.size(); ++i) {
    const SuspensionSample& s = stored[i];
    if (s.index != static_cast<int>(i) || s.time_step < 0 || s.time_step > step ||
        (i > 0 && s.time_step <= stored[i - 1].time_step)) {
      return refused("sample " + std::to_string(i) + " out of order");
    }
  }
  if (stored.back().time_step != step) return refused("the last sample is not at the checkpoint's step");
  if (fluid_step != step_word || swapped > 1 || current > 1)
    return refused("fluid phase disagrees with the step");
  if (snapshot_index > max_snapshots + 1) return refused("snapshot index out of range");
  if (builds == 0 || builds > step_word) return refused("contact list builds out of range");
  if (updates > step_word / marking_every) return refused("marking updates out of range");
  if (contact_pairs > cells.size() * cells.size()) return refused("contact pair count out of range");
  for (const std::vector<double>& x : restored.positions)
    if (!all_finite(x)) return refused("non-finite vertex positions");
  if (!all_finite(loop.contact_built_at)) return refused("non-finite contact list positions");
  for (const StoredFrame& f : loop.snapshots) {
    if (f.index < 0 || static_cast<std::uint64_t>(f.index) > snapshot_index || !std::isfinite(f.time_s))
      return refused("snapshot out of range");
  }
  lb::FluidPhase phase;
  phase.time_step = step;
  phase.aa_swapped = swapped == 1;
  phase.current = static_cast<int>(current);
  if (Status s = lb::set_fluid_phase(fluid, phase); !s.ok()) return refused(s.message());

  loop.snapshot_index = static_cast<int>(snapshot_index);
  loop.last_contact_pairs = static_cast<int>(contact_pairs);
  loop.contact_list_builds = static_cast<std::int64_t>(builds);
  loop.marking_updates = static_cast<std::int64_t>(updates);
  return restored;
}

}  // namespace cellflow::scenes::suspension_detail
