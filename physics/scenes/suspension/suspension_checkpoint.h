// Checkpoints of the suspension's time loop (internal to the scene; the
// public side is SuspensionCallbacks::checkpointing, the single cell's
// ShearFlowCheckpointing).
//
// Format, version 1, the conventions of the single-cell format
// (physics/scenes/shear_flow/shear_flow_checkpoint.h, word layer
// checkpoint_io.h): a flat binary file of little-endian 64-bit words,
// checked by a header and a payload checksum, another magic.
//
//   header, 21 words: magic "CFLWSUSP", format version, spec hash,
//     nx, ny, nz, precision (0 double, 1 float), streaming (0 AA, 1 two-array),
//     cell count, vertex count (all cells), hash of the cells (each cell's
//     kind, reference mesh and marker scale), time step, sample count,
//     snapshot count, contact vertex count (the surface vertices of all
//     cells), marking (1: a viscosity contrast, the nodes inside cells are
//     marked), population bytes, wall-density bytes, payload bytes, payload
//     checksum, header checksum (of the 20 words before it)
//   payload: snapshot index, contact pairs of the last step, fluid phase
//     (step, AA swap, two-array half), contact list builds, marking updates;
//     every cell's vertex positions (3 per vertex, cell after cell); the
//     positions at which the contact Verlet list was last built (3 per
//     contact vertex); the samples (12 words and 10 per cell each); the
//     snapshots (index, time, every cell's positions); the population bytes;
//     the wall-density bytes.
//
// Not in the file, because it is rebuilt exactly from what is: the contact
// Verlet list (rebuilt from its build positions, so the same pairs in the
// same order), the marking (the resume re-marks the restored positions
// exactly; checkpoints fall on marking steps, where the band update of the
// uninterrupted run equals the exact test), the averaging series and the
// largest contact count (from the samples). The vertex velocities and forces
// are rewritten each step before they are read; the scene draws no random
// numbers after the placement (done by the plan).
//
// Reading checks, before anything of the run is changed: the magic, the
// version and the header checksum; every dimension against this run
// (lattice, precision, streaming, cells, vertices, contact vertices,
// marking, spec hash); every count against the bound the schedule allows at
// that step; the payload size against the counts and the file size; then
// the payload checksum; then the samples' order and steps, the fluid phase
// and the finiteness of the positions. Only the populations are read in
// place: a refused file leaves the fluid to be re-initialised by the caller.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "physics/core/status.h"
#include "physics/coupling/immersed_cell.h"
#include "physics/lb/fluid.h"
#include "physics/scenes/suspension/suspension.h"

namespace cellflow::scenes::suspension_detail {

inline constexpr std::uint32_t kSuspensionCheckpointFormatVersion = 1;

// Every cell's positions of one snapshot as emitted (lattice units, cell
// after cell), kept for checkpoints so that a resumed run's recorder gets
// every frame.
struct StoredFrame {
  int index = 0;
  double time_s = 0.0;
  std::vector<double> x_lb;
};

// What this run is; a checkpoint must match it.
struct CheckpointLayout {
  std::uint64_t spec_hash = 0;
  std::uint64_t cells_hash = 0;  // cells_hash()
  std::size_t contact_vertices = 0;
  bool marking = false;
  std::int64_t sample_steps = 1;
  std::int64_t snapshot_steps = 0;  // 0: no snapshots
  std::int64_t max_steps = 0;
  std::int64_t marking_every = 1;  // checkpoints fall on marking steps when marking
};

// The time loop's state beyond the fluid, the cells' positions and the samples.
struct LoopState {
  int snapshot_index = 0;
  int last_contact_pairs = 0;
  std::int64_t contact_list_builds = 0;
  std::int64_t marking_updates = 0;
  std::vector<double> contact_built_at;  // RepulsionSearch::built_positions()
  std::vector<StoredFrame> snapshots;
};

// Hash of each cell's kind, reference mesh (positions and tets) and marker
// scale, to refuse a checkpoint of other cells (another mesher version).
std::uint64_t cells_hash(const coupling::ImmersedCells& cells, std::span<const int> cell_kind);

// Writes the state after `step` to path + ".tmp", then renames it to path.
// Returns the bytes written.
StatusOr<std::uint64_t> write_checkpoint(const CheckpointLayout& layout, const coupling::ImmersedCells& cells,
                                         const LoopState& loop, std::span<const SuspensionSample> samples,
                                         const lb::Fluid& fluid, std::int64_t step, const std::string& path);

struct RestoredState {
  std::int64_t step = 0;                       // the run continues after it
  std::vector<std::vector<double>> positions;  // per cell, lattice units
  LoopState loop;
  std::vector<SuspensionSample> samples;
};

// Reads `path` for a run of this layout and these cells. On success the
// fluid holds the populations and phase of the checkpoint; on an error the
// cells are unchanged and the fluid's populations may be overwritten (the
// caller re-initialises them).
StatusOr<RestoredState> read_checkpoint(const std::string& path, const CheckpointLayout& layout,
                                        const coupling::ImmersedCells& cells, lb::Fluid& fluid);

}  // namespace cellflow::scenes::suspension_detail
