#include "server/memory_estimate.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <system_error>

namespace cellflow::server {

namespace {

constexpr std::int64_t kBaselineBytes = 64LL << 20;   // process, gRPC, HDF5
constexpr std::int64_t kBytesPerVertex = 16LL << 10;  // see the header
constexpr int kDefaultVertexCount = 3000;             // CellSpec.target_vertex_count default

std::int64_t vertex_count(const v1::CellSpec& cell) {
  if (!cell.mesh_file().empty()) {
    // A Gmsh ASCII node line is at least ~30 bytes, and tetrahedron lines
    // outnumber node lines: file size / 30 bounds the vertex count.
    std::error_code error;
    const auto size = std::filesystem::file_size(cell.mesh_file(), error);
    return error ? 20000 : static_cast<std::int64_t>(size / 30);
  }
  return cell.has_target_vertex_count() ? std::max(cell.target_vertex_count(), 0) : kDefaultVertexCount;
}

std::int64_t shear_flow_bytes(const v1::ShearFlowSpec& flow) {
  const auto& n = flow.numerics();
  const double per_radius = n.has_cells_per_radius() ? n.cells_per_radius() : 6.0;
  const double bx = n.has_box_x_radii() ? n.box_x_radii() : 10.0;
  const double by = n.has_box_y_radii() ? n.box_y_radii() : 15.0;
  const double bz = n.has_box_z_radii() ? n.box_z_radii() : 5.0;
  const double nodes = std::ceil(bx * per_radius) * std::ceil(by * per_radius) * std::ceil(bz * per_radius);
  const double value_bytes = n.has_single_precision() && n.single_precision() ? 4.0 : 8.0;
  // Two population sets of 19 values, density, velocity and force (7 doubles).
  const double per_node = 2 * 19 * value_bytes + 7 * 8.0;
  const double lattice = std::isfinite(nodes) ? nodes * per_node : 1e300;
  return static_cast<std::int64_t>(std::min(lattice, 9e18)) + vertex_count(flow.cell()) * kBytesPerVertex;
}

}  // namespace

std::int64_t estimate_job_memory_bytes(const v1::JobSpec& spec) {
  switch (spec.scene_case()) {
    case v1::JobSpec::kCompression:
      return kBaselineBytes + vertex_count(spec.compression().cell()) * kBytesPerVertex;
    case v1::JobSpec::kIndentation:
      return kBaselineBytes + vertex_count(spec.indentation().cell()) * kBytesPerVertex;
    case v1::JobSpec::kShearFlow:
      return kBaselineBytes + shear_flow_bytes(spec.shear_flow());
    case v1::JobSpec::SCENE_NOT_SET:
      break;
  }
  return kBaselineBytes;
}

}  // namespace cellflow::server
