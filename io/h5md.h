// Job results as HDF5 files in the H5MD 1.1 layout (https://nongnu.org/h5md/)
// with its units module (unit attributes in the module's syntax: "m",
// "m s-1", "kg m-3"; a dimensionless quantity has no unit attribute):
//
//   /h5md                       attribute version = {1, 1}; groups author
//                               (name), creator (name, version)
//   /h5md/modules/units         attributes version = {1, 0}, system = "SI"
//   /particles/<group>/box      attributes dimension = 3, boundary = one of
//                               "periodic" / "none" per axis; edges (a
//                               time-dependent element, value [frames][3][3],
//                               m: the edge vectors as rows, a diagonal
//                               matrix of the box lengths) when the box has a
//                               size (set_box), one record per position frame
//   /particles/<group>/position/{step, time, value}   value: [frames][N][3], unit m
//   /connectivity/<group>       [M][4] vertex indices of the tetrahedra;
//                               attribute particles_group: an object
//                               reference to /particles/<group>
//   /connectivity/<group>_region  [M] region id per tetrahedron (0 cytoplasm, 1 nucleus)
//   /observables/<name>/{step, time, value}   value: [n] or [n][width],
//                               float64 or (counts) int64
//   /parameters/job_spec_json   the job spec (protobuf JSON mapping), a string
//   /parameters/<name>, /summary/<name>   scalars (attribute unit), integers,
//                               integer arrays and strings
//   /fields/<name>/{step, time, value}   one H5MD-style time series of a
//                               vector field on a uniform grid, value
//                               [frames][nz][ny][nx][3] float32 (H5MD has no
//                               Eulerian fields: a cellflow extension beside
//                               the H5MD groups); /fields/<name> attributes
//                               dimensions (nx, ny, nz), spacing_m, origin_m
//                               (node (0, 0, 0))
//
// step is an integer index (time step or load point), time a float: physical
// time in s, or, with H5mdCreator::time_unit empty, a dimensionless load
// parameter whose meaning the time datasets' attribute "meaning" names.
//
// The writer is generic: frames of positions, named time series, vector
// fields, scalars and a JSON string, so every scene (quasi-static curves,
// shear flow) writes through it.
// It flushes on flush(); a process killed after a flush leaves a file that
// opens and holds every record written before that flush.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "physics/core/status.h"

namespace cellflow::io {

struct H5mdCreator {
  std::string author = "cellflow";        // /h5md/author name
  std::string program = "cellflow";       // /h5md/creator name
  std::string program_version = "0.1.0";  // /h5md/creator version
  // Unit of the "time" datasets (H5MD units syntax); empty: dimensionless,
  // no unit attribute. Quasi-static scenes have no physical time: they store
  // the load parameter (deformation) there, without a unit, and say what it
  // is in time_meaning (attribute "meaning" of every time dataset).
  std::string time_unit = "s";
  std::string time_meaning;
};

// The simulation box of a particle group: per axis periodic or not, and its
// edge lengths (metres) where it has a size (the flow box); without edges the
// group lives in unbounded space (H5MD: edges only describe a box).
struct H5mdBox {
  bool periodic[3] = {false, false, false};
  bool has_edges = false;
  double edges_m[3] = {0.0, 0.0, 0.0};
};

// A node-centred grid: node (i, j, k) at origin_m + (i, j, k) spacing_m;
// element i + nx (j + ny k) of each component array.
struct UniformGrid {
  int nx = 0, ny = 0, nz = 0;
  double spacing_m = 0.0;
  double origin_m[3] = {0.0, 0.0, 0.0};
};

// A time series read back from /observables/<name>.
struct TimeSeries {
  std::vector<std::int64_t> step;
  std::vector<double> time;
  std::vector<double> value;  // step.size() * width values, row-major
  int width = 1;              // values per step
};

class H5mdWriter {
 public:
  // Creates `path`, replacing an existing file.
  static StatusOr<std::unique_ptr<H5mdWriter>> create(const std::string& path,
                                                      const H5mdCreator& creator = {});
  ~H5mdWriter();
  H5mdWriter(const H5mdWriter&) = delete;
  H5mdWriter& operator=(const H5mdWriter&) = delete;

  // The tetrahedra of particle group `group` (4 vertex indices each) and an
  // optional region id per tetrahedron (empty: none stored).
  Status write_tetrahedra(std::string_view group, std::span<const std::int32_t> tets,
                          std::span<const std::uint8_t> region);
  // The box of particle group `group` (before its first positions; default:
  // boundary none on every axis, no edges).
  Status set_box(std::string_view group, const H5mdBox& box);
  // Appends one frame of positions (3 per particle, metres) at (step, time),
  // and of the box edges when the box has them. Every frame of a group has
  // the same particle count.
  Status append_positions(std::string_view group, std::int64_t step, double time,
                          std::span<const double> positions_m);
  // Appends one record to /observables/<name>; the width (values.size()) and
  // the unit (H5MD units syntax, empty: dimensionless) are fixed by the first record.
  Status append_observable(std::string_view name, std::int64_t step, double time,
                           std::span<const double> values, std::string_view unit = "");
  Status append_observable(std::string_view name, std::int64_t step, double time, double value,
                           std::string_view unit = "") {
    return append_observable(name, step, time, std::span<const double>(&value, 1), unit);
  }
  // A count (iterations, splits): an observable of int64 values, dimensionless.
  Status append_count(std::string_view name, std::int64_t step, double time, std::int64_t value);
  // Appends one frame of the vector field /fields/<name> (three component
  // arrays of grid.nx * ny * nz values). Stored as float32: the frames are for
  // viewing, and the lattice they come from stores float by default. Every
  // frame of a field has the grid and unit (H5MD units syntax) of the first.
  Status append_vector_field(std::string_view name, std::int64_t step, double time, const UniformGrid& grid,
                             std::span<const double> x, std::span<const double> y, std::span<const double> z,
                             std::string_view unit = "");
  // A scalar dataset at `path` (e.g. "/summary/steady_taylor_deformation")
  // with an attribute unit (if not empty); an int64 scalar (a count or an
  // index, dimensionless); a string dataset at `path`.
  Status write_scalar(std::string_view path, double value, std::string_view unit = "");
  Status write_integer(std::string_view path, std::int64_t value);
  Status write_string(std::string_view path, std::string_view value);
  // A one-dimensional int64 dataset at `path` (e.g. the kind of each cell of
  // a suspension, /parameters/setup/cell_kind).
  Status write_integers(std::string_view path, std::span<const std::int64_t> values);
  // Stores the job spec JSON as /parameters/job_spec_json (written once).
  Status write_parameters_json(std::string_view json);
  // Makes everything written so far durable in the file.
  Status flush();
  // Flushes and closes; the destructor does the same, ignoring errors.
  Status close();

  const std::string& path() const { return path_; }

 private:
  struct Impl;
  H5mdWriter(std::string path, std::unique_ptr<Impl> impl);
  std::string path_;
  std::unique_ptr<Impl> impl_;
};

// Reads /observables/<name>.
StatusOr<TimeSeries> read_observable(const std::string& path, std::string_view name);
// Names of the groups under /observables, sorted.
StatusOr<std::vector<std::string>> list_observables(const std::string& path);
// /parameters/job_spec_json.
StatusOr<std::string> read_parameters_json(const std::string& path);
// A dataset written by write_scalar, write_integer (converted) or write_string.
StatusOr<double> read_scalar(const std::string& path, std::string_view dataset);
StatusOr<std::string> read_string(const std::string& path, std::string_view dataset);
// Frames stored for /fields/<name> (0 when there is no such field).
StatusOr<int> count_field_frames(const std::string& path, std::string_view name);
// Frame `frame` of /particles/<group>/position/value as 3 * N doubles, with its step and time.
struct PositionFrame {
  std::int64_t step = 0;
  double time = 0.0;
  std::vector<double> positions_m;
};
StatusOr<PositionFrame> read_position_frame(const std::string& path, std::string_view group, int frame);
// Number of position frames stored for `group`.
StatusOr<int> count_position_frames(const std::string& path, std::string_view group);

}  // namespace cellflow::io
