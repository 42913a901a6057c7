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

// The doubles of a 1-D dataset (the time of a series).
std::vector<double> read_doubles(hid_t file, const std::string& path) {
  const std::vector<hsize_t> dims = dims_of(file, path);
  std::vector<double> values(dims.size() == 1 ? dims[0] : 0);
  Handle dataset(H5Dopen2(file, path.c_str(), H5P_DEFAULT));
  if (!values.empty() &&
      H5Dread(dataset.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values.data()) < 0)
    values.clear();
  return values;
}

std::string join(const std::vector<hsize_t>& values) {
  std::string out;
  for (hsize_t v : values) out += (out.empty() ? "" : " ") + std::to_string(v);
  return out;
}

// Record `record` of the dataset `path` of dimensions `dims` (records first)
// as an XDMF HyperSlab: start, stride and count per dimension, then the
// whole dataset. No copy of the record is stored.
std::string hyperslab(const std::string& ref, const std::string& path, const std::vector<hsize_t>& dims,
                      hsize_t record, const char* number_type, int precision, const std::string& indent) {
  std::vector<hsize_t> start(dims.size(), 0), stride(dims.size(), 1), count = dims;
  start[0] = record;
  count[0] = 1;
  const std::string rank = std::to_string(dims.size());
  std::string xml;
  xml += indent + "<DataItem ItemType=\"HyperSlab\" Dimensions=\"" + join(count) + "\" Type=\"HyperSlab\">\n";
  xml += indent + "  <DataItem Dimensions=\"3 " + rank + "\" Format=\"XML\">" + join(start) + " " +
         join(stride) + " " + join(count) + "</DataItem>\n";
  xml += indent + "  <DataItem Dimensions=\"" + join(dims) + "\" NumberType=\"" + number_type +
         "\" Precision=\"" + std::to_string(precision) + "\" Format=\"HDF\">" + ref + ":" + path +
         "</DataItem>\n";
  xml += indent + "</DataItem>\n";
  return xml;
}

// The index of the last of `times` at or before `t` (0 when none is).
std::size_t frame_at(const std::vector<double>& times, double t) {
  std::size_t frame = 0;
  for (std::size_t i = 0; i < times.size(); ++i) {
    if (times[i] <= t) frame = i;
  }
  return frame;
}

// What the sidecar shows of a particle group: its tetrahedra and the frames
// of /particles/<group>/position/value.
struct ParticleGrids {
  std::string group;
  std::vector<hsize_t> tet_dims, position_dims;
  bool has_region = false;
  std::vector<double> times;
};

// What it shows of a vector field /fields/<name>: the grid and the frames of its value.
struct FieldGrids {
  std::string name;
  int dimensions[3] = {0, 0, 0};
  double spacing = 0.0, origin[3] = {0.0, 0.0, 0.0};
  std::vector<hsize_t> value_dims;
  std::vector<double> times;
};

StatusOr<ParticleGrids> particle_grids(hid_t file, std::string_view group) {
  ParticleGrids grids;
  grids.group = group;
  const std::string connectivity = "/connectivity/" + grids.group;
  const std::string position = "/particles/" + grids.group + "/position";
  grids.tet_dims = dims_of(file, connectivity);
  if (grids.tet_dims.size() != 2 || grids.tet_dims[1] != 4)
    return Status(StatusCode::kInternal, connectivity + " is not [M][4]");
  grids.position_dims = dims_of(file, position + "/value");
  if (grids.position_dims.size() != 3 || grids.position_dims[2] != 3)
    return Status(StatusCode::kInternal, position + "/value is not [frames][N][3]");
  grids.times = read_doubles(file, position + "/time");
  if (grids.times.size() != grids.position_dims[0])
    return Status(StatusCode::kInternal, position + ": time and value lengths differ");
  grids.has_region = path_exists(file, connectivity + "_region");
  return grids;
}

StatusOr<FieldGrids> field_grids(hid_t file, const std::string& name) {
  FieldGrids grids;
  grids.name = name;
  const std::string base = "/fields/" + name;
  Handle group(H5Gopen2(file, base.c_str(), H5P_DEFAULT));
  {
    Handle d(H5Aopen(group.get(), "dimensions", H5P_DEFAULT));
    Handle s(H5Aopen(group.get(), "spacing_m", H5P_DEFAULT));
    Handle o(H5Aopen(group.get(), "origin_m", H5P_DEFAULT));
    if (!d.valid() || !s.valid() || !o.valid() || H5Aread(d.get(), H5T_NATIVE_INT, grids.dimensions) < 0 ||
        H5Aread(s.get(), H5T_NATIVE_DOUBLE, &grids.spacing) < 0 ||
        H5Aread(o.get(), H5T_NATIVE_DOUBLE, grids.origin) < 0) {
      return Status(StatusCode::kInternal, base + " lacks its grid attributes");
    }
  }
  if (!path_exists(file, base + "/value") || !path_exists(file, base + "/time"))
    return Status(StatusCode::kInternal, base + " has no value or time");
  grids.value_dims = dims_of(file, base + "/value");
  const std::vector<hsize_t> expected = {
      grids.value_dims.empty() ? 0 : grids.value_dims[0], static_cast<hsize_t>(grids.dimensions[2]),
      static_cast<hsize_t>(grids.dimensions[1]), static_cast<hsize_t>(grids.dimensions[0]), 3};
  if (grids.value_dims != expected)
    return Status(StatusCode::kInternal, base + "/value is not [frames][nz][ny][nx][3]");
  grids.times = read_doubles(file, base + "/time");
  if (grids.times.size() != grids.value_dims[0])
    return Status(StatusCode::kInternal, base + ": time and value lengths differ");
  return grids;
}

// Frame `frame` of the particle group as a tetrahedral grid named after the group.
std::string particle_grid(const ParticleGrids& grids, std::size_t frame, const std::string& ref) {
  const std::string connectivity = "/connectivity/" + grids.group;
  const std::string tets = std::to_string(grids.tet_dims[0]);
  const std::string indent = "          ";
  std::string xml;
  xml += "        <Grid Name=\"" + xml_escape(grids.group) + "\" GridType=\"Uniform\">\n";
  xml += "          <Topology TopologyType=\"Tetrahedron\" NumberOfElements=\"" + tets + "\">\n";
  xml += "            <DataItem Dimensions=\"" + tets +
         " 4\" NumberType=\"Int\" Precision=\"4\" Format=\"HDF\">" + ref + ":" + xml_escape(connectivity) +
         "</DataItem>\n";
  xml += "          </Topology>\n";
  xml += "          <Geometry GeometryType=\"XYZ\">\n";
  xml += hyperslab(ref, xml_escape("/particles/" + grids.group + "/position/value"), grids.position_dims,
                   frame, "Float", 8, indent + "  ");
  xml += "          </Geometry>\n";
  if (grids.has_region) {
    xml += "          <Attribute Name=\"region\" AttributeType=\"Scalar\" Center=\"Cell\">\n";
    xml += "            <DataItem Dimensions=\"" + tets +
           "\" NumberType=\"UChar\" Precision=\"1\" Format=\"HDF\">" + ref + ":" +
           xml_escape(connectivity + "_region") + "</DataItem>\n";
    xml += "          </Attribute>\n";
  }
  xml += "        </Grid>\n";
  return xml;
}

// Frame `frame` of the field as a 3DCoRectMesh named after the field, the
// field node-centred. XDMF 2 orders the grid's dimensions, origin and
// spacing slowest first (z, y, x), as the frames are stored.
std::string field_grid(const FieldGrids& grids, std::size_t frame, const std::string& ref) {
  const std::string zyx = std::to_string(grids.dimensions[2]) + " " + std::to_string(grids.dimensions[1]) +
                          " " + std::to_string(grids.dimensions[0]);
  std::string xml;
  xml += "        <Grid Name=\"" + xml_escape(grids.name) + "\" GridType=\"Uniform\">\n";
  xml += "          <Topology TopologyType=\"3DCoRectMesh\" Dimensions=\"" + zyx + "\"/>\n";
  xml += "          <Geometry GeometryType=\"ORIGIN_DXDYDZ\">\n";
  xml += "            <DataItem Dimensions=\"3\" NumberType=\"Float\" Precision=\"8\" Format=\"XML\">" +
         format_double(grids.origin[2]) + " " + format_double(grids.origin[1]) + " " +
         format_double(grids.origin[0]) + "</DataItem>\n";
  xml += "            <DataItem Dimensions=\"3\" NumberType=\"Float\" Precision=\"8\" Format=\"XML\">" +
         format_double(grids.spacing) + " " + format_double(grids.spacing) + " " +
         format_double(grids.spacing) + "</DataItem>\n";
  xml += "          </Geometry>\n";
  xml += "          <Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">\n";
  xml += hyperslab(ref, xml_escape("/fields/" + grids.name + "/value"), grids.value_dims, frame, "Float", 4,
                   "            ");
  xml += "          </Attribute>\n";
  xml += "        </Grid>\n";
  return xml;
}

// Names of the groups under /fields, sorted.
std::vector<std::string> field_names(hid_t file) {
  std::vector<std::string> names;
  if (!path_exists(file, "/fields")) return names;
  Handle handle(H5Gopen2(file, "/fields", H5P_DEFAULT));
  H5G_info_t info;
  H5Gget_info(handle.get(), &info);
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
  const std::string position = "/particles/" + std::string(group) + "/position/value";
  std::vector<ParticleGrids> particles;
  if (path_exists(file.get(), connectivity) && path_exists(file.get(), position) &&
      dims_of(file.get(), position).size() == 3 && dims_of(file.get(), position)[0] > 0) {
    auto grids = particle_grids(file.get(), group);
    if (!grids.ok()) return grids.status();
    particles.push_back(std::move(*grids));
  }
  std::vector<FieldGrids> fields;
  for (const std::string& name : field_names(file.get())) {
    auto grids = field_grids(file.get(), name);
    if (!grids.ok()) return grids.status();
    if (!grids->times.empty()) fields.push_back(std::move(*grids));
  }
  if (particles.empty() && fields.empty()) {
    return Status(StatusCode::kNotFound,
                  "no " + connectivity + " with frames in " + position + ", and no /fields");
  }
  // The times of every frame of every grid: at each, the latest frame of each
  // grid at or before it (the first before its own first).
  std::vector<double> times;
  for (const ParticleGrids& p : particles) times.insert(times.end(), p.times.begin(), p.times.end());
  for (const FieldGrids& f : fields) times.insert(times.end(), f.times.begin(), f.times.end());
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end()), times.end());

  const std::string ref = xml_escape(h5_reference);
  std::string xml;
  xml += "<?xml version=\"1.0\" ?>\n";
  xml += "<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n";
  xml += "<Xdmf Version=\"2.0\">\n";
  xml += "  <Domain>\n";
  // One temporal collection of spatial collections: both ParaView readers
  // (XDMF3 and the legacy one) then give a multiblock data set with one block
  // per grid, named after it (cell, fluid_velocity), at every time.
  xml += "    <Grid Name=\"result\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (std::size_t t = 0; t < times.size(); ++t) {
    xml += "      <Grid Name=\"frame_" + std::to_string(t) +
           "\" GridType=\"Collection\" CollectionType=\"Spatial\">\n";
    xml += "        <Time Value=\"" + format_double(times[t]) + "\"/>\n";
    for (const ParticleGrids& p : particles) xml += particle_grid(p, frame_at(p.times, times[t]), ref);
    for (const FieldGrids& f : fields) xml += field_grid(f, frame_at(f.times, times[t]), ref);
    xml += "      </Grid>\n";
  }
  xml += "    </Grid>\n";
  xml += "  </Domain>\n";
  xml += "</Xdmf>\n";
  return xml;
}

Status write_xdmf(const std::string& h5_path, const std::string& xdmf_path, std::string_view group) {
  const std::size_t slash = h5_path.find_last_of('/');
  const std::string base = slash == std::string::npos ? h5_path : h5_path.substr(slash + 1);
  // "./name", relative: the XDMF3 reader prepends the XDMF file's directory
  // to any relative heavy-data path (Xdmf3 XdmfCoreItemFactory::
  // getFullHeavyDataPath); a bare name is what issue 16 saw the readers miss.
  auto xml = xdmf_for(h5_path, group, "./" + base);
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
