// Spherical tetrahedral meshes from a real mesher (TetGen), Gmsh .msh v4 ASCII
// import, and a mesh-quality report.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "physics/core/status.h"
#include "physics/mesh/tet_mesh.h"

namespace cellflow::mesh {

// The default mesh size of a cell (every scene; docs/accuracy shows why).
inline constexpr int kDefaultSphereVertexCount = 3000;

// The range make_sphere_mesh accepts: a cell radius of 0.1 um to 1 cm, and
// target vertex counts from 200 to 20000.
inline constexpr double kMinSphereRadiusM = 1e-7;
inline constexpr double kMaxSphereRadiusM = 1e-2;
inline constexpr int kMinSphereVertexCount = 200;
inline constexpr int kMaxSphereVertexCount = 20000;

// Grading towards the poles (0, 0, +-R), where the contact scenes' plates and
// probe touch the cell: the surface edge length is pole_spacing_m at the
// poles and grows by `growth` times the arc distance from the nearer pole up
// to the uniform mesh's spacing h (graded_sphere_surface.h); the interior
// follows the same sizing of the distance from the nearer pole (TetGen
// refines every tet whose circumradius exceeds 0.9 times it at the
// circumcentre). target_vertex_count then sets the
// bulk (h and the interior volume bound of the uniform mesh of that count),
// and the grading adds vertices near the poles (about 2 pi / (0.87 growth^2)
// ln(h / pole_spacing_m) on the surface of each pole).
struct PoleGrading {
  double pole_spacing_m = 0.0;  // 0: uniform geodesic mesh; else in [1e-3 R, h) (>= h: uniform)
  double growth = 0.15;         // in [0.1, 1]
  // Each ring vertex moved along its meridian by up to +-ring_jitter / 2 of
  // the ring distance and the surface re-triangulated to its convex hull
  // (graded_sphere_surface.h), so the plates and the probe take the vertices
  // into contact one by one, not a ring at once; in [0, 1]. 1 (the heights
  // of a ring spread over its whole band) took the probe curves' largest
  // step against a local fit of the CalculiX references from 1.071 / 1.101
  // (0: plain rings) to 1.029 / 1.041 (the references' own 1.010 / 1.019)
  // and their error from 2.79 / 3.48 % to 2.51 / 3.03 %
  // (validation/fe/compare_cellflow.py, 2026-12-04).
  double ring_jitter = 1.0;
};

struct SphereMeshOptions {
  double radius_m = 0.0;  // R in [kMinSphereRadiusM, kMaxSphereRadiusM]
  int target_vertex_count =
      kDefaultSphereVertexCount;       // about; kMinSphereVertexCount ... kMaxSphereVertexCount
  double nucleus_radius_m = 0.0;       // > 0: concentric nucleus region (tets marked Region::kNucleus)
  double max_radius_edge_ratio = 1.5;  // TetGen quality bound (-q); 1.1 ... 10
  double min_dihedral_deg = 10.0;      // TetGen quality bound (-q/..); 0 ... 18
  PoleGrading pole_grading;            // default: none
};

// Surface edge length h of the uniform sphere mesh make_sphere_mesh makes for
// this radius and vertex count (the geodesic sphere's mean edge); 0 for
// arguments out of make_sphere_mesh's range.
double sphere_mesh_spacing_m(double radius_m, int target_vertex_count);

// Deterministic: the same options give the same mesh.
// Geodesic (subdivided icosahedron) surface with every boundary vertex exactly
// on the sphere (the nucleus surface likewise on radius nucleus_radius_m) and
// an icosahedron vertex at both poles (0, 0, +-R), the contact points of the
// plates and the probe, for every vertex count;
// filled by TetGen (-pq<ratio>/<dihedral>Y -a<volume>) with a uniform edge
// length; the volume bound is iterated until the vertex count is within 3 %
// of the target (within 15 % guaranteed). Tets are positively oriented; a
// sliver pass moves free interior vertices until every dihedral angle
// exceeds min_dihedral_deg without breaking the radius-edge bound.
// Meshing runs on a sphere normalised by a power of two and is scaled back,
// so the result does not depend on the unit beyond that exact scaling.
// With pole_grading.pole_spacing_m in (0, h): the pole-graded ring surface
// instead of the geodesic one (both poles are vertices too), the interior
// volume bound of the uniform mesh, one TetGen run; a graded mesh of more
// than kMaxSphereVertexCount vertices (half that on its surface, or made)
// -> kInvalidArgument naming pole_grading.pole_spacing_m.
// Invalid options (any double, NaN and infinities included, any int) ->
// kInvalidArgument naming the field and its range, never a crash; the
// nucleus must leave a shell of at least half a mesh spacing
// (nucleus_radius_m < radius_m - h/2, h the surface edge length).
StatusOr<TetMesh> make_sphere_mesh(const SphereMeshOptions& options);

// Gmsh MSH 4.1 ASCII: $Nodes and $Elements (4-node tetrahedra, type 4). A
// physical group named "nucleus" (or physical tag 2) marks nucleus tets.
// Coordinates are taken in metres times `length_scale_m` (1 = file in metres).
// Missing/unreadable file -> kNotFound/kInvalidArgument; inverted or degenerate
// tetrahedra -> kFailedPrecondition naming the element.
// Details: other element types and unknown sections are skipped; nodes that
// no tetrahedron uses are dropped; node order is kept otherwise. A tet is
// inverted when det[x1-x0, x2-x0, x3-x0] < 0 in Gmsh's node order, degenerate
// when |V| <= 1e-12 of the mean |V|; the nodes are reordered to the
// tet_mesh.h convention. Errors in the text carry "path:line:".
// write_gmsh_msh: MSH 4.1 ASCII, physical groups 1 "cytoplasm" and 2
// "nucleus" (one volume entity each), coordinates with 17 significant digits
// so that read_gmsh_msh(write_gmsh_msh(m)) reproduces m bitwise.
//
// Hostile input: read_gmsh_msh reads `path` only if it is a regular file
// (directories, FIFOs, devices, sockets -> kInvalidArgument; checked with
// stat before and fstat after an O_NONBLOCK open, so nothing blocks), of at
// most limits.max_bytes (else kResourceExhausted), whose size as read equals
// the size stat reported (procfs/sysfs pseudo-files -> kInvalidArgument).
// Declared counts above limits.max_nodes / max_elements -> kResourceExhausted,
// counts the remaining bytes cannot hold -> kInvalidArgument, both before any
// allocation, naming "path:line:" and the count. Error messages never repeat
// the file's content.
struct MeshReadLimits {
  std::uint64_t max_bytes = std::uint64_t{64} << 20;  // 64 MiB
  long long max_nodes = 2'000'000;                    // numNodes of $Nodes
  long long max_elements = 2'000'000;                 // numElements of $Elements (all types)
};
StatusOr<TetMesh> read_gmsh_msh(const std::string& path, double length_scale_m = 1.0,
                                const MeshReadLimits& limits = {});
// The same from bytes in memory (an upload); `name` stands for the path in
// messages. read_gmsh_msh is read_mesh_file_bytes + this.
StatusOr<TetMesh> read_gmsh_msh_from_bytes(std::string_view bytes, std::string_view name = "<mesh bytes>",
                                           double length_scale_m = 1.0, const MeshReadLimits& limits = {});
// The bytes of a regular file of at most limits.max_bytes (the checks above).
StatusOr<std::string> read_mesh_file_bytes(const std::string& path, const MeshReadLimits& limits = {});
Status write_gmsh_msh(const TetMesh& mesh, const std::string& path);

struct MeshQuality {
  std::size_t num_vertices = 0, num_tets = 0, num_surface_vertices = 0;
  double min_dihedral_deg = 0.0;
  double max_dihedral_deg = 0.0;
  double max_radius_edge_ratio = 0.0;  // circumradius / shortest edge, worst tet
  double volume_m3 = 0.0;
  double min_tet_volume_m3 = 0.0;
  double mean_edge_length_m = 0.0;
};
MeshQuality mesh_quality(const TetMesh& mesh);

}  // namespace cellflow::mesh
