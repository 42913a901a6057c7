// Checkpoints of the shear-flow time loop (internal to the scene; the public
// side is ShearFlowCheckpointing in shear_flow.h).
//
// Format, version 1: a flat binary file, little-endian 64-bit words
// throughout (the machines cellflow runs on; a big-endian reader refuses the
// magic). Why not HDF5 through io/: the physics library does not link HDF5,
// a checkpoint is opaque to everyone but this file (the server and the worker
// only move its bytes), and a flat layout is read with one bounded pass and
// checked by one checksum, with nothing of a general-purpose container
// parser exposed to a hostile file.
//
//   header, 20 words: magic "CFLWCKPT", format version, spec hash,
//     nx, ny, nz, precision (bit 0: float populations, bit 1: float elastic
//     forces), streaming (0 AA, 1 two-array),
//     vertex count, tet count, hash of the reference mesh (positions and tets),
//     time step, sample count, snapshot count, tank-treading vertex count,
//     population bytes, wall-density bytes, payload bytes, payload checksum,
//     header checksum (of the 19 words before it)
//   payload: last elastic energy, snapshot index, fluid phase (step, AA swap,
//     two-array half); vertex positions (3 nv doubles); positions at the last
//     sample (3 nv); tank-treading angles and unwrapped angles (per tracked
//     vertex) and the mean unwrapped angle per sample; the samples (16 words
//     each); the snapshots (index, time, 3 nv doubles each); the population
//     bytes; the wall-density bytes.
//
// Reading checks, before anything of the run is changed: the magic, the
// version and the header checksum; every dimension against this run (lattice,
// precision, streaming, mesh, spec hash); every count against the bound the
// schedule allows at that step; the payload size against the counts and the
// file size; then the payload checksum; then the samples' indices and steps
// and the positions' finiteness. Only the populations are read in place: a
// refused file leaves the fluid to be re-initialised by the caller.
#pragma once

#include <cstdint>
#include <string>

#include "physics/core/status.h"
#include "physics/lb/fluid.h"
#include "physics/scenes/shear_flow/checkpoint_io.h"
#include "physics/scenes/shear_flow/shear_flow.h"
#include "physics/scenes/shear_flow/shear_flow_internal.h"

namespace cellflow::scenes::shear_flow_detail {

inline constexpr std::uint32_t kCheckpointFormatVersion = 1;

// Hash of the reference mesh (positions and tets), to refuse a checkpoint
// of a different mesh (another mesher version on another machine).
std::uint64_t mesh_hash(const mesh::TetMesh& mesh);

// checkpoint_precision_word of a run's fluid and cells (every cell has the
// scene's elastic precision), for both formats.
std::uint64_t precision_word(const lb::Fluid& fluid, const coupling::ImmersedCells& cells);

// Writes the state after `step` to path + ".tmp", then renames it to path.
// Returns the bytes written.
StatusOr<std::uint64_t> write_checkpoint(const Run& run, const ShearFlowResult& result,
                                         const lb::Fluid& fluid, std::int64_t step, std::uint64_t spec_hash,
                                         const std::string& path);

// Restores run, result.samples and the fluid from `path`; returns the step to
// continue after. On an error run and result are unchanged and the fluid's
// populations may be overwritten (the caller re-initialises them).
StatusOr<std::int64_t> read_checkpoint(const std::string& path, std::uint64_t spec_hash,
                                       const Schedule& schedule, Run& run, ShearFlowResult& result,
                                       lb::Fluid& fluid);

}  // namespace cellflow::scenes::shear_flow_detail
