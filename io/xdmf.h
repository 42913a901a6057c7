// XDMF 2 sidecar of an H5MD result, so ParaView (the default XDMF3 reader and
// the legacy "XDMF Reader") opens the cell mesh as a time series, and beside
// it the vector fields of /fields (the fluid velocity of a shear-flow job) on
// their uniform grids: one temporal collection of spatial collections, each
// grid a block named after the particle group or field. It stores no data of
// its own: the tetrahedra are /connectivity/<group>, each frame a HyperSlab
// of /particles/<group>/position/value or /fields/<name>/value.
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

// Writes xdmf_for(h5_path, group, "./" + basename(h5_path)) to `xdmf_path`
// (which belongs beside the HDF5 file).
Status write_xdmf(const std::string& h5_path, const std::string& xdmf_path, std::string_view group = "cell");

}  // namespace cellflow::io
