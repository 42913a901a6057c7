// An upper estimate of a job's peak memory, so that jobs too large for the
// machine are refused before they are queued (RESOURCE_EXHAUSTED).
#pragma once

#include <cstdint>

#include "cellflow/v1/spec.pb.h"

namespace cellflow::server {

// Quasi-static scenes: a fixed process baseline (64 MiB) plus 16 KiB per
// vertex for the mesh, the elastic precomputation, the 3N x 3N sparse tangent
// and its incomplete Cholesky factor. Measured peak RSS of cellflow-run
// (one load point): 23 MB at 3000 vertices, 62 MB at 10000, i.e. about
// 5.5 KiB per vertex; the estimate keeps a margin of about three.
// Shear flow: the D3Q19 lattice as physics/lb allocates it (in-place AA
// streaming: ONE population array of 19 values per node, plus the force and
// velocity fields, 3 values each, in the storage precision; lb::memory_bytes
// via scenes::plan_shear_flow), the larger of the transient per-node buffers
// in double (the Couette start profile, 2 values; the fluid velocity
// snapshots, 3 values, when numerics.fluid_snapshots is set), and the cell
// mesh at the quasi-static rate per vertex.
std::int64_t estimate_job_memory_bytes(const v1::JobSpec& spec);

}  // namespace cellflow::server
