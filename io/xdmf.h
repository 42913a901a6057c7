// XDMF 2 sidecar of an H5MD result, so ParaView ("XDMF Reader", the legacy
// reader) opens the cell meshes as a time series, and beside them the vector
// fields of /fields (the fluid velocity of a shear-flow job) on their uniform
// grids. It references only whole datasets (no HyperSlab): the tetrahedra in
// /connectivity/<group>, one 2-D copy of each position frame in
// /xdmf/<group>/frame_<k>, and each field frame /fields/<name>/frame_<k>.
#pragma once

#include <string>
#include <string_view>

#include "physics/core/status.h"

namespace cellflow::io {

// The XDMF text for particle group `group` of `h5_path` (if it has frames)
// and every field under /fields; kNotFound when there is neither. Datasets are named
// relative to `h5_reference` (what the XDMF file will find beside itself,
// usually the HDF5 file's base name).
StatusOr<std::string> xdmf_for(const std::string& h5_path, std::string_view group,
                               const std::string& h5_reference);

// Writes xdmf_for(h5_path, group, basename(h5_path)) to `xdmf_path`.
Status write_xdmf(const std::string& h5_path, const std::string& xdmf_path, std::string_view group = "cell");

}  // namespace cellflow::io
