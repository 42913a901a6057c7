#include "physics/io/xdmf.h"

#include <hdf5.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <vector>

#include "physics/io/h5_handle.h"

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
  const std::string region = connectivity + "_region";
  const std::string frames_group = "/xdmf/" + std::string(group);
  if (!path_exists(file.get(), connectivity)) return Status(StatusCode::kNotFound, "no " + connectivity);
  if (!path_exists(file.get(), frames_group)) return Status(StatusCode::kNotFound, "no " + frames_group);

  // Frames in creation order: their names sort that way (frame_%06d).
  Handle frames(H5Gopen2(file.get(), frames_group.c_str(), H5P_DEFAULT));
  H5G_info_t info;
  H5Gget_info(frames.get(), &info);
  std::vector<std::string> names;
  for (hsize_t i = 0; i < info.nlinks; ++i) {
    const ssize_t size =
        H5Lget_name_by_idx(frames.get(), ".", H5_INDEX_NAME, H5_ITER_INC, i, nullptr, 0, H5P_DEFAULT);
    std::string name(static_cast<std::size_t>(size), '\0');
    H5Lget_name_by_idx(frames.get(), ".", H5_INDEX_NAME, H5_ITER_INC, i, name.data(), name.size() + 1,
                       H5P_DEFAULT);
    names.push_back(name);
  }
  std::sort(names.begin(), names.end());

  const std::vector<hsize_t> tet_dims = dims_of(file.get(), connectivity);
  if (tet_dims.size() != 2 || tet_dims[1] != 4)
    return Status(StatusCode::kInternal, connectivity + " is not [M][4]");
  const std::string tets = std::to_string(tet_dims[0]);
  const std::string ref = xml_escape(h5_reference);
  const bool has_region = path_exists(file.get(), region);

  std::string xml;
  xml += "<?xml version=\"1.0\" ?>\n";
  xml += "<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n";
  xml += "<Xdmf Version=\"2.0\">\n";
  xml += "  <Domain>\n";
  xml +=
      "    <Grid Name=\"" + xml_escape(group) + "\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (const std::string& name : names) {
    const std::string frame_path = frames_group + "/" + name;
    const std::vector<hsize_t> dims = dims_of(file.get(), frame_path);
    if (dims.size() != 2 || dims[1] != 3) return Status(StatusCode::kInternal, frame_path + " is not [N][3]");
    double time = 0.0;
    {
      Handle dataset(H5Dopen2(file.get(), frame_path.c_str(), H5P_DEFAULT));
      Handle attr(H5Aopen(dataset.get(), "time", H5P_DEFAULT));
      if (!attr.valid() || H5Aread(attr.get(), H5T_NATIVE_DOUBLE, &time) < 0) {
        return Status(StatusCode::kInternal, frame_path + " has no time attribute");
      }
    }
    xml += "      <Grid Name=\"" + xml_escape(name) + "\" GridType=\"Uniform\">\n";
    xml += "        <Time Value=\"" + format_double(time) + "\"/>\n";
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
