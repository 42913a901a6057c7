#include "io/xdmf.h"

#include <hdf5.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <vector>

#include "io/h5_handle.h"

namespace cellflow::io {

using detail::Handle;
using detail::path_exists;

namespace {

std::string xml_escape(std::string_view text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::vector<hsize_t> dims_of(hid_t file, const std::string& path) {
  Handle dataset(H5Dopen2(file, path.c_str(), H5P_DEFAULT));
  Handle space(H5Dget_space(dataset.get()));
  std::vector<hsize_t> dims(std::max(H5Sget_simple_extent_ndims(space.get()), 0));
  H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr);
  return dims;
}

std::string format_double(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.17g", value);
  return buffer;
}

}  // namespace

namespace {

// Names of the links in `group`, sorted (frame_%06d sorts in creation order).
std::vector<std::string> sorted_children(hid_t file, const std::string& group) {
  Handle handle(H5Gopen2(file, group.c_str(), H5P_DEFAULT));
  H5G_info_t info;
  H5Gget_info(handle.get(), &info);
  std::vector<std::string> names;
  for (hsize_t i = 0; i < info.nlinks; ++i) {
    const ssize_t size =
        H5Lget_name_by_idx(handle.get(), ".", H5_INDEX_NAME, H5_ITER_INC, i, nullptr, 0, H5P_DEFAULT);
    std::string name(static_cast<std::size_t>(size), '\0');
    H5Lget_name_by_idx(handle.get(), ".", H5_INDEX_NAME, H5_ITER_INC, i, name.data(), name.size() + 1,
                       H5P_DEFAULT);
    names.push_back(name);
  }
  std::sort(names.begin(), names.end());
  return names;
}

StatusOr<double> frame_time(hid_t file, const std::string& frame_path) {
  double time = 0.0;
  Handle dataset(H5Dopen2(file, frame_path.c_str(), H5P_DEFAULT));
  Handle attr(H5Aopen(dataset.get(), "time", H5P_DEFAULT));
  if (!attr.valid() || H5Aread(attr.get(), H5T_NATIVE_DOUBLE, &time) < 0) {
    return Status(StatusCode::kInternal, frame_path + " has no time attribute");
  }
  return time;
}

// The temporal collection of particle group `group`: one tetrahedral grid per
// position frame copy in /xdmf/<group>.
StatusOr<std::string> particle_collection(hid_t file, std::string_view group, const std::string& ref) {
  const std::string connectivity = "/connectivity/" + std::string(group);
  const std::string region = connectivity + "_region";
  const std::string frames_group = "/xdmf/" + std::string(group);
  const std::vector<hsize_t> tet_dims = dims_of(file, connectivity);
  if (tet_dims.size() != 2 || tet_dims[1] != 4)
    return Status(StatusCode::kInternal, connectivity + " is not [M][4]");
  const std::string tets = std::to_string(tet_dims[0]);
  const bool has_region = path_exists(file, region);

  std::string xml;
  xml +=
      "    <Grid Name=\"" + xml_escape(group) + "\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (const std::string& name : sorted_children(file, frames_group)) {
    const std::string frame_path = frames_group + "/" + name;
    const std::vector<hsize_t> dims = dims_of(file, frame_path);
    if (dims.size() != 2 || dims[1] != 3) return Status(StatusCode::kInternal, frame_path + " is not [N][3]");
    auto time = frame_time(file, frame_path);
    if (!time.ok()) return time.status();
    xml += "      <Grid Name=\"" + xml_escape(name) + "\" GridType=\"Uniform\">\n";
    xml += "        <Time Value=\"" + format_double(*time) + "\"/>\n";
    xml += "        <Topology TopologyType=\"Tetrahedron\" NumberOfElements=\"" + tets + "\">\n";
    xml += "          <DataItem Dimensions=\"" + tets +
           " 4\" NumberType=\"Int\" Precision=\"4\" Format=\"HDF\">" + ref + ":" + connectivity +
           "</DataItem>\n";
    xml += "        </Topology>\n";
    xml += "        <Geometry GeometryType=\"XYZ\">\n";
    xml += "          <DataItem Dimensions=\"" + std::to_string(dims[0]) +
           " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" + ref + ":" + frame_path +
           "</DataItem>\n";
    xml += "        </Geometry>\n";
    if (has_region) {
      xml += "        <Attribute Name=\"region\" AttributeType=\"Scalar\" Center=\"Cell\">\n";
      xml += "          <DataItem Dimensions=\"" + tets +
             "\" NumberType=\"UChar\" Precision=\"1\" Format=\"HDF\">" + ref + ":" + region + "</DataItem>\n";
      xml += "        </Attribute>\n";
    }
    xml += "      </Grid>\n";
  }
  xml += "    </Grid>\n";
  return xml;
}

// The temporal collection of vector field /fields/<name>: a 3DCoRectMesh per
// frame, the field node-centred. XDMF 2 orders the grid's dimensions, origin
// and spacing slowest first (z, y, x), as the frames are stored.
StatusOr<std::string> field_collection(hid_t file, const std::string& name, const std::string& ref) {
  const std::string base = "/fields/" + name;
  Handle group(H5Gopen2(file, base.c_str(), H5P_DEFAULT));
  int dimensions[3] = {0, 0, 0};
  double spacing = 0.0, origin[3] = {0.0, 0.0, 0.0};
  {
    Handle d(H5Aopen(group.get(), "dimensions", H5P_DEFAULT));
    Handle s(H5Aopen(group.get(), "spacing_m", H5P_DEFAULT));
    Handle o(H5Aopen(group.get(), "origin_m", H5P_DEFAULT));
    if (!d.valid() || !s.valid() || !o.valid() || H5Aread(d.get(), H5T_NATIVE_INT, dimensions) < 0 ||
        H5Aread(s.get(), H5T_NATIVE_DOUBLE, &spacing) < 0 ||
        H5Aread(o.get(), H5T_NATIVE_DOUBLE, origin) < 0) {
      return Status(StatusCode::kInternal, base + " lacks its grid attributes");
    }
  }
  const std::string zyx = std::to_string(dimensions[2]) + " " + std::to_string(dimensions[1]) + " " +
                          std::to_string(dimensions[0]);
  std::string xml;
  xml += "    <Grid Name=\"" + xml_escape(name) + "\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (const std::string& frame : sorted_children(file, base)) {
    if (frame.rfind("frame_", 0) != 0) continue;  // step and time
    const std::string frame_path = base + "/" + frame;
    auto time = frame_time(file, frame_path);
    if (!time.ok()) return time.status();
    xml += "      <Grid Name=\"" + xml_escape(frame) + "\" GridType=\"Uniform\">\n";
    xml += "        <Time Value=\"" + format_double(*time) + "\"/>\n";
    xml += "        <Topology TopologyType=\"3DCoRectMesh\" Dimensions=\"" + zyx + "\"/>\n";
    xml += "        <Geometry GeometryType=\"ORIGIN_DXDYDZ\">\n";
    xml += "          <DataItem Dimensions=\"3\" NumberType=\"Float\" Precision=\"8\" Format=\"XML\">" +
           format_double(origin[2]) + " " + format_double(origin[1]) + " " + format_double(origin[0]) +
           "</DataItem>\n";
    xml += "          <DataItem Dimensions=\"3\" NumberType=\"Float\" Precision=\"8\" Format=\"XML\">" +
           format_double(spacing) + " " + format_double(spacing) + " " + format_double(spacing) +
           "</DataItem>\n";
    xml += "        </Geometry>\n";
    xml += "        <Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">\n";
    xml += "          <DataItem Dimensions=\"" + zyx +
           " 3\" NumberType=\"Float\" Precision=\"4\" Format=\"HDF\">" + ref + ":" + frame_path +
           "</DataItem>\n";
    xml += "        </Attribute>\n";
    xml += "      </Grid>\n";
  }
  xml += "    </Grid>\n";
  return xml;
}

}  // namespace

StatusOr<std::string> xdmf_for(const std::string& h5_path, std::string_view group,
                               const std::string& h5_reference) {
  hid_t file_id = H5I_INVALID_HID;
  H5E_BEGIN_TRY {
    file_id = H5Fopen(h5_path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  }
  H5E_END_TRY;
  if (file_id < 0) return Status(StatusCode::kNotFound, "cannot open HDF5 file " + h5_path);
  Handle file(file_id);

  const std::string connectivity = "/connectivity/" + std::string(group);
  const std::string frames_group = "/xdmf/" + std::string(group);
  const bool has_particles = path_exists(file.get(), connectivity) && path_exists(file.get(), frames_group);
  const std::vector<std::string> fields = path_exists(file.get(), "/fields")
                                              ? sorted_children(file.get(), "/fields")
                                              : std::vector<std::string>{};
  if (!has_particles && fields.empty()) {
    return Status(StatusCode::kNotFound,
                  "no " + connectivity + " with frames in " + frames_group + ", and no /fields");
  }
  const std::string ref = xml_escape(h5_reference);
  std::string xml;
  xml += "<?xml version=\"1.0\" ?>\n";
  xml += "<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n";
  xml += "<Xdmf Version=\"2.0\">\n";
  xml += "  <Domain>\n";
  // One temporal collection per particle group and per field: ParaView reads
  // them as blocks of one data set and shows the cell inside the flow.
  if (has_particles) {
    auto particles = particle_collection(file.get(), group, ref);
    if (!particles.ok()) return particles.status();
    xml += *particles;
  }
  for (const std::string& name : fields) {
    auto field = field_collection(file.get(), name, ref);
    if (!field.ok()) return field.status();
    xml += *field;
  }
  xml += "  </Domain>\n";
  xml += "</Xdmf>\n";
  return xml;
}

Status write_xdmf(const std::string& h5_path, const std::string& xdmf_path, std::string_view group) {
  const std::size_t slash = h5_path.find_last_of('/');
  const std::string base = slash == std::string::npos ? h5_path : h5_path.substr(slash + 1);
  auto xml = xdmf_for(h5_path, group, base);
  if (!xml.ok()) return xml.status();
  const std::string temporary = xdmf_path + ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out << *xml;
    if (!out) return {StatusCode::kInternal, "cannot write " + temporary};
  }
  if (std::rename(temporary.c_str(), xdmf_path.c_str()) != 0) {
    return {StatusCode::kInternal, "cannot rename " + temporary + " to " + xdmf_path};
  }
  return {};
}

}  // namespace cellflow::io
