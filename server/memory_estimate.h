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
// Shear flow: the D3Q19 lattice (two population sets, 19 values each, plus
// density, velocity and force fields) over the box in lattice cells, plus
// the cell mesh.
std::int64_t estimate_job_memory_bytes(const v1::JobSpec& spec);

}  // namespace cellflow::server
