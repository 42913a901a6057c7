// Sphere meshing: a geodesic (subdivided icosahedron) surface triangulation
// projected onto the sphere, closed by TetGen into a quality constrained
// Delaunay tetrahedralization. The surface is preserved exactly (-Y), so every
// boundary vertex lies on the sphere; the interior density follows a
// maximum-volume bound tuned until the vertex count meets the target.
#include "physics/mesh/sphere_mesh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "physics/core/violations.h"
#include "physics/mesh/graded_sphere_surface.h"
#include "physics/mesh/tet_geometry.h"
#include "physics/mesh/vertex_order.h"

#define TETLIBRARY  // TetGen throws an int on failure instead of calling exit()
#include <tetgen.h>

namespace cellflow::mesh {
namespace {

constexpr int kMinVertexCount = kMinSphereVertexCount;
constexpr int kMaxVertexCount = kMaxSphereVertexCount;

using SurfaceMesh = SphereSurface;

// Geodesic sphere of the given frequency: every face of the icosahedron is
// split into frequency^2 triangles on a barycentric grid and each grid point is
// projected onto the sphere. 10 f^2 + 2 vertices, 20 f^2 triangles. Grid points
// are keyed by their integer barycentric weights on the icosahedron vertices,
// so points on shared edges are merged exactly (no floating-point matching).
// The 12 vertices of the icosahedron, unit length, turned about the x axis so
// that vertex 5 lies on +z and vertex 6 on -z: every geodesic sphere then has
// a vertex at both poles, where the plates and the probe of the contact scenes
// first touch. Without the turn, odd frequencies put an edge at the poles and
// the mesh's height falls short of 2 R (0.9977 * 2 R at 3000 vertices), which
// shifted the force curves by up to 2 % from one vertex count to the next.
std::array<std::array<double, 3>, 12> icosahedron() {
  const double phi = (1.0 + std::sqrt(5.0)) / 2.0;
  const std::array<std::array<double, 3>, 12> corners = {{{-1, phi, 0},
                                                          {1, phi, 0},
                                                          {-1, -phi, 0},
                                                          {1, -phi, 0},
                                                          {0, -1, phi},
                                                          {0, 1, phi},
                                                          {0, -1, -phi},
                                                          {0, 1, -phi},
                                                          {phi, 0, -1},
                                                          {phi, 0, 1},
                                                          {-phi, 0, -1},
                                                          {-phi, 0, 1}}};
  // rotation about x by atan(1 / phi) takes (0, 1, phi) to (0, 0, |.|)
  const double norm = std::sqrt(1.0 + phi * phi);
  const double sin_a = 1.0 / norm, cos_a = phi / norm;
  std::array<std::array<double, 3>, 12> unit;
  for (std::size_t v = 0; v < corners.size(); ++v) {
    const auto& c = corners[v];
    unit[v] = {c[0] / norm, (c[1] * cos_a - c[2] * sin_a) / norm, (c[1] * sin_a + c[2] * cos_a) / norm};
  }
  return unit;
}

SurfaceMesh make_geodesic_sphere(int frequency, double radius_m) {
  const std::array<std::array<double, 3>, 12> ico = icosahedron();
  const std::array<std::array<int, 3>, 20> faces = {
      {{0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
       {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
       {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}}};
  const int n = frequency;
  SurfaceMesh surface;
  surface.points.reserve(3 * static_cast<std::size_t>(10 * n * n + 2));
  surface.triangles.reserve(static_cast<std::size_t>(20 * n * n));
  // Key: (vertex, weight) pairs with nonzero weight, sorted by vertex.
  std::map<std::array<int, 6>, int> index_of;

  auto point_index = [&](const std::array<int, 3>& face, int i, int j) {
    const int k = n - i - j;
    std::array<std::pair<int, int>, 3> w = {{{face[0], k}, {face[1], i}, {face[2], j}}};
    std::sort(w.begin(), w.end());
    std::array<int, 6> key{-1, 0, -1, 0, -1, 0};
    int m = 0;
    for (const auto& [vertex, weight] : w) {
      if (weight > 0) {
        key[2 * m] = vertex;
        key[2 * m + 1] = weight;
        ++m;
      }
    }
    auto [it, inserted] = index_of.try_emplace(key, static_cast<int>(surface.points.size() / 3));
    if (inserted) {
      double p[3];
      for (int d = 0; d < 3; ++d) {
        p[d] = (k * ico[face[0]][d] + i * ico[face[1]][d] + j * ico[face[2]][d]) / n;
      }
      const double norm = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
      for (double c : p) surface.points.push_back(radius_m * c / norm);
    }
    return it->second;
  };

  for (const auto& face : faces) {
    for (int i = 0; i < n; ++i) {
      for (int j = 0; i + j < n; ++j) {
        const int a = point_index(face, i, j);
        const int b = point_index(face, i + 1, j);
        const int c = point_index(face, i, j + 1);
        surface.triangles.push_back({a, b, c});
        if (i + j + 1 < n) {
          const int d = point_index(face, i + 1, j + 1);
          surface.triangles.push_back({b, d, c});
        }
      }
    }
  }
  return surface;
}

// Local quality of vertex v: the smallest dihedral angle over its tets, or -1
// when one of them is inverted or flat or exceeds the radius-edge bound.
double vertex_quality(const TetMesh& mesh, const std::vector<int>& first, const std::vector<int>& incident,
                      int v, double max_radius_edge_ratio) {
  double worst = 180.0;
  for (int i = first[v]; i < first[v + 1]; ++i) {
    const std::int32_t* tet = &mesh.tets[4 * static_cast<std::size_t>(incident[i])];
    if (tet_signed_volume6(mesh.positions_m.data(), tet) <= 0.0) return -1.0;
    if (tet_radius_edge_ratio(mesh.positions_m.data(), tet) > max_radius_edge_ratio) return -1.0;
    worst = std::min(worst, tet_dihedral_range(mesh.positions_m.data(), tet).min_deg);
  }
  return worst;
}

// TetGen's dihedral bound is not a guarantee: with the surface held fixed
// (-Y) a few slivers with two boundary vertices survive next to the sphere.
// Each vertex of such a sliver is moved to the best of a few candidate
// positions (towards the centroid of its neighbours, away from the sliver's
// opposite face, small axis steps) when that raises the smallest dihedral
// angle of its tets. Interior vertices go first; vertices of the outer surface
// and of the nucleus interface move only when needed and only along their
// sphere (candidates projected back onto it), so both surfaces keep every
// vertex on their spheres. Deterministic: fixed visiting order.
void remove_slivers(TetMesh& mesh, double bound_deg, double max_radius_edge_ratio, double outer_radius_m,
                    double nucleus_radius_m) {
  const int num_vertices = static_cast<int>(mesh.num_vertices());
  const int num_tets = static_cast<int>(mesh.num_tets());
  std::vector<int> first(static_cast<std::size_t>(num_vertices) + 1, 0);
  for (std::int32_t v : mesh.tets) ++first[static_cast<std::size_t>(v) + 1];
  for (int v = 0; v < num_vertices; ++v) first[v + 1] += first[v];
  std::vector<int> incident(mesh.tets.size());
  {
    std::vector<int> fill(first.begin(), first.end() - 1);
    for (int t = 0; t < num_tets; ++t) {
      for (int k = 0; k < 4; ++k) incident[fill[mesh.tets[4 * t + k]]++] = t;
    }
  }
  // Vertices on the outer surface and on the nucleus interface (vertices
  // with tets of both regions) may only slide on their sphere: their
  // candidates are projected back onto it. 0 marks a free vertex.
  std::vector<std::uint8_t> region_mask(static_cast<std::size_t>(num_vertices), 0);
  for (int t = 0; t < num_tets; ++t) {
    const auto bit = static_cast<std::uint8_t>(1u << static_cast<unsigned>(mesh.tet_region[t]));
    for (int k = 0; k < 4; ++k) region_mask[mesh.tets[4 * t + k]] |= bit;
  }
  std::vector<double> sphere_radius(static_cast<std::size_t>(num_vertices), 0.0);
  for (int v = 0; v < num_vertices; ++v) {
    if (mesh.on_surface[v] != 0) {
      sphere_radius[v] = outer_radius_m;
    } else if (region_mask[v] == 3) {
      sphere_radius[v] = nucleus_radius_m;
    }
  }
  const double target_deg = bound_deg + 0.5;
  double* x = mesh.positions_m.data();
  for (int pass = 0; pass < 20; ++pass) {
    std::vector<int> movable;
    for (int t = 0; t < num_tets; ++t) {
      const std::int32_t* tet = &mesh.tets[4 * static_cast<std::size_t>(t)];
      if (tet_dihedral_range(x, tet).min_deg >= target_deg) continue;
      for (int k = 0; k < 4; ++k) movable.push_back(tet[k]);
    }
    if (movable.empty()) return;
    // Free vertices first; surface vertices move only where that was not enough.
    std::sort(movable.begin(), movable.end(), [&](int a, int b) {
      const bool ca = sphere_radius[a] > 0.0;
      const bool cb = sphere_radius[b] > 0.0;
      return ca != cb ? cb : a < b;
    });
    movable.erase(std::unique(movable.begin(), movable.end()), movable.end());
    bool moved = false;
    for (int v : movable) {
      const std::array<double, 3> start = {x[3 * v], x[3 * v + 1], x[3 * v + 2]};
      // A move may not push a tet past the radius-edge bound (or past its
      // current ratio where TetGen already left it above).
      double ratio_bound = max_radius_edge_ratio;
      for (int i = first[v]; i < first[v + 1]; ++i) {
        ratio_bound = std::max(
            ratio_bound, tet_radius_edge_ratio(x, &mesh.tets[4 * static_cast<std::size_t>(incident[i])]));
      }
      const double start_quality = vertex_quality(mesh, first, incident, v, ratio_bound);
      if (start_quality >= target_deg) continue;
      std::vector<std::array<double, 3>> candidates;
      std::array<double, 3> centroid{};
      double neighbour_distance = 0.0;
      int count = 0;
      for (int i = first[v]; i < first[v + 1]; ++i) {
        const std::int32_t* tet = &mesh.tets[4 * static_cast<std::size_t>(incident[i])];
        for (int k = 0; k < 4; ++k) {
          if (tet[k] == v) continue;
          double d2 = 0.0;
          for (int d = 0; d < 3; ++d) {
            centroid[d] += x[3 * tet[k] + d];
            d2 += (x[3 * tet[k] + d] - start[d]) * (x[3 * tet[k] + d] - start[d]);
          }
          neighbour_distance += std::sqrt(d2);
          ++count;
        }
        // Away from the face opposite v, by a fraction of the tet's size.
        if (tet_dihedral_range(x, tet).min_deg >= target_deg) continue;
        int k0 = 0;
        while (tet[k0] != v) ++k0;
        const double* a = x + 3 * tet[(k0 + 1) % 4];
        const double* b = x + 3 * tet[(k0 + 2) % 4];
        const double* c = x + 3 * tet[(k0 + 3) % 4];
        const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        const double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        const double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        const double n_len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        const double side = n[0] * (start[0] - a[0]) + n[1] * (start[1] - a[1]) + n[2] * (start[2] - a[2]);
        const double size = std::sqrt(std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) *
                                      std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]));
        const double sign = side >= 0.0 ? 1.0 : -1.0;
        for (double step : {0.05, 0.1, 0.2}) {
          candidates.push_back({start[0] + sign * step * size * n[0] / n_len,
                                start[1] + sign * step * size * n[1] / n_len,
                                start[2] + sign * step * size * n[2] / n_len});
        }
      }
      for (double& c : centroid) c /= count;
      for (double step : {1.0, 0.5, 0.25}) {
        candidates.push_back({start[0] + step * (centroid[0] - start[0]),
                              start[1] + step * (centroid[1] - start[1]),
                              start[2] + step * (centroid[2] - start[2])});
      }
      // Fallback: steps along the coordinate axes, scaled by the mean
      // distance to the neighbours.
      const double local = neighbour_distance / count;
      for (int d = 0; d < 3; ++d) {
        for (double step : {-0.3, -0.1, 0.1, 0.3}) {
          std::array<double, 3> c = start;
          c[d] += step * local;
          candidates.push_back(c);
        }
      }
      if (sphere_radius[v] > 0.0) {
        for (auto& c : candidates) {
          const double r = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
          for (double& component : c) component *= sphere_radius[v] / r;
        }
      }
      double best_quality = start_quality;
      std::array<double, 3> best = start;
      for (const auto& candidate : candidates) {
        for (int d = 0; d < 3; ++d) x[3 * v + d] = candidate[d];
        const double q = vertex_quality(mesh, first, incident, v, ratio_bound);
        if (q > best_quality + 1e-9) {
          best_quality = q;
          best = candidate;
        }
      }
      for (int d = 0; d < 3; ++d) x[3 * v + d] = best[d];
      moved = moved || best != start;
    }
    if (!moved) return;
  }
}

double mean_edge_length(const SurfaceMesh& s) {
  double total = 0.0;
  for (const auto& tri : s.triangles) {
    for (int k = 0; k < 3; ++k) {
      const double* a = &s.points[3 * static_cast<std::size_t>(tri[k])];
      const double* b = &s.points[3 * static_cast<std::size_t>(tri[(k + 1) % 3])];
      total += std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                         (a[2] - b[2]) * (a[2] - b[2]));
    }
  }
  return total / (3.0 * static_cast<double>(s.triangles.size()));
}

// One TetGen run over the outer surface (and the nucleus surface, an internal
// facet, when present) with the given maximum tetrahedron volume. The
// surfaces are in normalised units (outer radius in [1, 2), see
// make_sphere_mesh) and `scale` (a power of two) takes them to metres; the
// volume bound (normalised) goes to TetGen as round9(max_volume scale^3) /
// scale^3, round9 the 9 digits of the switch string, so that the normalised
// mesh is the exact power-of-two image of the mesh TetGen makes in metres.
// A sizing for TetGen's refinement: the wanted edge length h(x) at a point.
// A tet is refined while its circumradius exceeds kCircumradiusPerEdge
// h(circumcentre) (TetGen inserts the circumcentre). The regular tet of edge
// h has circumradius 0.61 h; 0.9 gives the vertex count of TetGen's own -m
// on the uniform mesh as background (colloidal probe: 4907 against 4815
// vertices), which interpolated h linearly inside the background's tets and
// spent two thirds of the meshing time locating points in it (meshing 1.58
// -> 0.52 s); against CalculiX the probes' largest errors fell from 2.87 to
// 2.70 % (colloidal) and 4.11 to 3.43 % (small probe). 1.0 gave 4407
// vertices and 3.61 % (validation/fe/compare_cellflow.py, 2026-12-02).
struct Sizing {
  std::function<double(const double*)> edge_length;  // normalised units; empty: none
};
constexpr double kCircumradiusPerEdge = 0.9;

// TetGen's TetSizeFunc carries no user data: the sizing of the run in
// progress, set and cleared while tetgen_mutex (tetrahedralize_spheres) is
// held, so that only one run at a time reads it.
const Sizing* active_sizing = nullptr;

// R_c > kCircumradiusPerEdge h(c), c the circumcentre: c - a solves
// 2 [u v w]^T (c - a) = (|u|^2, |v|^2, |w|^2) with u, v, w the edges from a.
bool tet_above_sizing(REAL* a, REAL* b, REAL* c, REAL* d, REAL* /*edge lengths*/, REAL /*volume*/) {
  double u[3], v[3], w[3];
  for (int k = 0; k < 3; ++k) {
    u[k] = b[k] - a[k];
    v[k] = c[k] - a[k];
    w[k] = d[k] - a[k];
  }
  auto dot = [](const double* p, const double* q) { return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]; };
  const double vw[3] = {v[1] * w[2] - v[2] * w[1], v[2] * w[0] - v[0] * w[2], v[0] * w[1] - v[1] * w[0]};
  const double wu[3] = {w[1] * u[2] - w[2] * u[1], w[2] * u[0] - w[0] * u[2], w[0] * u[1] - w[1] * u[0]};
  const double uv[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
  const double det = 2.0 * dot(u, vw);
  if (!(std::abs(det) > 0.0)) return false;  // flat: TetGen's quality pass handles it
  double centre[3], radius2 = 0.0;
  for (int k = 0; k < 3; ++k) {
    const double offset = (dot(u, u) * vw[k] + dot(v, v) * wu[k] + dot(w, w) * uv[k]) / det;
    centre[k] = a[k] + offset;
    radius2 += offset * offset;
  }
  const double h = kCircumradiusPerEdge * active_sizing->edge_length(centre);
  return radius2 > h * h;
}

StatusOr<TetMesh> tetrahedralize_spheres(const std::vector<SurfaceMesh>& surfaces, double max_volume,
                                         double outer_radius, double nucleus_radius, double scale,
                                         const SphereMeshOptions& options, const Sizing& sizing = {}) {
  const bool with_nucleus = surfaces.size() > 1;
  const double outer_radius_m = outer_radius;
  const double nucleus_radius_m = nucleus_radius;
  const double scale3 = scale * scale * scale;
  tetgenio in;
  tetgenio out;
  in.firstnumber = 0;
  int num_points = 0;
  int num_facets = 0;
  for (const SurfaceMesh& s : surfaces) {
    num_points += static_cast<int>(s.points.size() / 3);
    num_facets += static_cast<int>(s.triangles.size());
  }
  in.numberofpoints = num_points;
  in.pointlist = new REAL[3 * static_cast<std::size_t>(num_points)];
  in.numberoffacets = num_facets;
  in.facetlist = new tetgenio::facet[static_cast<std::size_t>(num_facets)];
  int point_offset = 0;
  int facet_index = 0;
  for (const SurfaceMesh& s : surfaces) {
    std::copy(s.points.begin(), s.points.end(), in.pointlist + 3 * point_offset);
    for (const auto& tri : s.triangles) {
      tetgenio::facet& f = in.facetlist[facet_index++];
      tetgenio::init(&f);
      f.numberofpolygons = 1;
      f.polygonlist = new tetgenio::polygon[1];
      tetgenio::init(&f.polygonlist[0]);
      f.polygonlist[0].numberofvertices = 3;
      f.polygonlist[0].vertexlist = new int[3];
      for (int k = 0; k < 3; ++k) f.polygonlist[0].vertexlist[k] = tri[k] + point_offset;
    }
    point_offset += static_cast<int>(s.points.size() / 3);
  }
  if (with_nucleus) {
    // Region seeds: the centre lies inside the nucleus polyhedron (attribute
    // 1); the cytoplasm seed sits half-way between the two surfaces along the
    // direction of icosahedron vertex 0, a vertex of both geodesic spheres, so
    // it is strictly between the polyhedra (attribute 2).
    const std::array<double, 3> vertex0 = icosahedron()[0];
    const double shell = 0.5 * (nucleus_radius_m + outer_radius_m);
    in.numberofregions = 2;
    in.regionlist = new REAL[10]{
        0.0, 0.0, 0.0, 1.0, -1.0, shell * vertex0[0], shell * vertex0[1], shell * vertex0[2], 2.0, -1.0};
  }

  // p: PLC input; q: quality bound (radius-edge ratio / min dihedral); Y: keep
  // the surface triangulation (no Steiner points on the sphere); a: maximum
  // volume; A: region attributes; z: zero-based indices; Q: quiet.
  // The numbers are set on tetgenbehavior after parsing placeholders: TetGen's
  // parser stops at an exponent ("q1.5/1e-05" turned into switches 'e', '-',
  // ...), and the volume bound is set in normalised units. Their values are
  // those of the decimal text (%.6g, %.9g), as when TetGen parsed them.
  char ratio_text[32];
  char dihedral_text[32];
  char volume_text[32];
  std::snprintf(ratio_text, sizeof(ratio_text), "%.6g", options.max_radius_edge_ratio);
  std::snprintf(dihedral_text, sizeof(dihedral_text), "%.6g", options.min_dihedral_deg);
  std::snprintf(volume_text, sizeof(volume_text), "%.9g", max_volume * scale3);
  char switches[256];  // for messages: the equivalent command line, volume in m^3
  std::snprintf(switches, sizeof(switches), "pq%s/%sYa%szQ%s", ratio_text, dihedral_text, volume_text,
                with_nucleus ? "A" : "");
  tetgenbehavior behavior;
  {
    char placeholder[32];
    std::snprintf(placeholder, sizeof(placeholder), "pq2/1Ya1zQ%s", with_nucleus ? "A" : "");
    if (!behavior.parse_commandline(placeholder)) {
      return Status(StatusCode::kInternal, std::string("TetGen rejected the switches ") + switches);
    }
  }
  behavior.minratio = std::strtod(ratio_text, nullptr);
  behavior.mindihedral = std::strtod(dihedral_text, nullptr);
  behavior.maxvolume = std::strtod(volume_text, nullptr) / scale3;
  if (!(behavior.maxvolume > 0.0) || !std::isfinite(behavior.maxvolume)) {
    return Status(StatusCode::kInternal,
                  std::string("volume bound out of range (switches ") + switches + ")");
  }
  // The sizing replaces no bound: TetGen still refines to the volume and
  // quality bounds, and further wherever a tet is above the sizing.
  if (sizing.edge_length) in.tetunsuitable = tet_above_sizing;
  // TetGen keeps static tables and the exact-arithmetic constants of its
  // predicates in globals that every run rewrites: serialise the runs so that
  // meshing from several threads (parameter sweeps) is safe.
  static std::mutex tetgen_mutex;
  const std::lock_guard<std::mutex> lock(tetgen_mutex);
  active_sizing = &sizing;
  struct ClearSizing {
    ~ClearSizing() { active_sizing = nullptr; }
  } clear_sizing;
  try {
    tetrahedralize(&behavior, &in, &out);
  } catch (int code) {
    return Status(StatusCode::kInternal,
                  "TetGen failed with code " + std::to_string(code) + " (switches " + switches + ")");
  }
  if (out.numberoftetrahedra <= 0 || out.numberofcorners < 4) {
    return Status(StatusCode::kInternal, "TetGen produced no tetrahedra");
  }

  TetMesh mesh;
  mesh.positions_m.assign(out.pointlist, out.pointlist + 3 * static_cast<std::size_t>(out.numberofpoints));
  const std::size_t num_tets = static_cast<std::size_t>(out.numberoftetrahedra);
  mesh.tets.resize(4 * num_tets);
  mesh.tet_region.assign(num_tets, Region::kCytoplasm);
  for (std::size_t t = 0; t < num_tets; ++t) {
    const int* corner = out.tetrahedronlist + t * static_cast<std::size_t>(out.numberofcorners);
    std::int32_t* tet = &mesh.tets[4 * t];
    for (int k = 0; k < 4; ++k) tet[k] = corner[k];
    // Reorder to det[x1 - x4, x2 - x4, x3 - x4] > 0 (tet_mesh.h).
    if (tet_signed_volume6(mesh.positions_m.data(), tet) < 0.0) std::swap(tet[0], tet[1]);
    if (with_nucleus && out.numberoftetrahedronattributes > 0 &&
        std::lround(
            out.tetrahedronattributelist[t * static_cast<std::size_t>(out.numberoftetrahedronattributes)]) ==
            1) {
      mesh.tet_region[t] = Region::kNucleus;
    }
  }
  mark_surface_vertices(mesh);
  return mesh;
}

// Pole spacing in radii (below 1e-3 R the grading alone adds thousands of
// vertices at any growth) and growth per unit arc (below 0.1 the graded cap
// holds 2 pi / growth^2 times more vertices than a ring; above 1 neighbouring
// triangles differ by more than a factor 2).
constexpr double kMinPoleSpacingRadii = 1e-3, kMaxPoleSpacingRadii = 1.0;
constexpr double kMinPoleGrowth = 0.1, kMaxPoleGrowth = 1.0;
constexpr double kMaxRingJitter = 1.0;

// Size model, calibrated against TetGen 1.5 with the default quality bounds:
// a geodesic surface of frequency f with mean edge h, closed with maximum
// tet volume kUniformVolumeFactor h^3, gives interior edges of the same mean
// length h (a uniform mesh) and about 4.24 f^3 + 4.06 f^2 vertices in all.
constexpr double kUniformVolumeFactor = 0.175;

struct GeodesicSize {
  int frequency = 2;
  double volume_scale = 1.0;  // interior volume bound / kUniformVolumeFactor h^3
};

GeodesicSize geodesic_size(double target) {
  auto predicted_count = [](double f) { return 4.24 * f * f * f + 4.06 * f * f; };
  auto surface_count = [](int f) { return 10.0 * f * f + 2.0; };
  double f_real = 2.0;
  while (predicted_count(f_real + 0.01) < target) f_real += 0.01;
  // Of the two neighbouring frequencies take the one that needs the smaller
  // change of the interior volume bound (uniformity of the sizes).
  GeodesicSize size;
  double best_log = 1e300;
  for (int f : {static_cast<int>(std::floor(f_real)), static_cast<int>(std::ceil(f_real))}) {
    f = std::max(2, f);
    const double interior_wanted = target - surface_count(f);
    if (interior_wanted < 1.0) continue;
    // Interior vertex count scales like 1 / max volume.
    const double count_ratio = (predicted_count(f) - surface_count(f)) / interior_wanted;
    if (std::abs(std::log(count_ratio)) < best_log) {
      best_log = std::abs(std::log(count_ratio));
      size.frequency = f;
      size.volume_scale = count_ratio;
    }
  }
  return size;
}

// Short decimal form for messages: 8e-06 rather than to_string's 0.000008.
Status validate(const SphereMeshOptions& o) {
  // Written so that NaN fails every comparison and lands in the error.
  if (!(o.radius_m >= kMinSphereRadiusM && o.radius_m <= kMaxSphereRadiusM)) {
    return invalid_argument("radius_m must be in [" + number_text(kMinSphereRadiusM, 6) + ", " +
                            number_text(kMaxSphereRadiusM, 6) + "] m (0.1 um to 1 cm) (got " +
                            number_text(o.radius_m, 6) + ")");
  }
  if (o.target_vertex_count < kMinVertexCount || o.target_vertex_count > kMaxVertexCount) {
    return invalid_argument("target_vertex_count must be in [" + std::to_string(kMinVertexCount) + ", " +
                            std::to_string(kMaxVertexCount) + "] (got " +
                            std::to_string(o.target_vertex_count) + ")");
  }
  if (o.nucleus_radius_m != 0.0 && !(o.nucleus_radius_m > 0.0 && o.nucleus_radius_m < o.radius_m)) {
    return invalid_argument("nucleus_radius_m must be 0 (no nucleus) or in (0, radius_m) = (0, " +
                            number_text(o.radius_m, 6) + ") (got " + number_text(o.nucleus_radius_m, 6) +
                            ")");
  }
  if (!(o.max_radius_edge_ratio >= 1.1 && o.max_radius_edge_ratio <= 10.0)) {
    return invalid_argument("max_radius_edge_ratio must be in [1.1, 10] (got " +
                            number_text(o.max_radius_edge_ratio, 6) + ")");
  }
  if (!(o.min_dihedral_deg >= 0.0 && o.min_dihedral_deg <= 18.0)) {
    return invalid_argument("min_dihedral_deg must be in [0, 18] (got " + number_text(o.min_dihedral_deg, 6) +
                            ")");
  }
  const PoleGrading& g = o.pole_grading;
  if (g.pole_spacing_m != 0.0 && !(g.pole_spacing_m >= kMinPoleSpacingRadii * o.radius_m &&
                                   g.pole_spacing_m <= kMaxPoleSpacingRadii * o.radius_m)) {
    return invalid_argument("pole_grading.pole_spacing_m must be 0 (uniform) or in [" +
                            number_text(kMinPoleSpacingRadii, 6) + ", " +
                            number_text(kMaxPoleSpacingRadii, 6) + "] radius_m = [" +
                            number_text(kMinPoleSpacingRadii * o.radius_m, 6) + ", " +
                            number_text(kMaxPoleSpacingRadii * o.radius_m, 6) + "] m (got " +
                            number_text(g.pole_spacing_m, 6) + ")");
  }
  if (!(g.growth >= kMinPoleGrowth && g.growth <= kMaxPoleGrowth)) {
    return invalid_argument("pole_grading.growth must be in [" + number_text(kMinPoleGrowth, 6) + ", " +
                            number_text(kMaxPoleGrowth, 6) + "] (got " + number_text(g.growth, 6) + ")");
  }
  if (!(g.ring_jitter >= 0.0 && g.ring_jitter <= kMaxRingJitter)) {
    return invalid_argument("pole_grading.ring_jitter must be in [0, " + number_text(kMaxRingJitter, 6) +
                            "] (got " + number_text(g.ring_jitter, 6) + ")");
  }
  return Status::ok_status();
}

}  // namespace

double sphere_mesh_spacing_m(double radius_m, int target_vertex_count) {
  if (!(radius_m >= kMinSphereRadiusM && radius_m <= kMaxSphereRadiusM) ||
      target_vertex_count < kMinVertexCount || target_vertex_count > kMaxVertexCount) {
    return 0.0;
  }
  const double scale = std::ldexp(1.0, std::ilogb(radius_m));
  const GeodesicSize size = geodesic_size(target_vertex_count);
  return mean_edge_length(make_geodesic_sphere(size.frequency, radius_m / scale)) * scale;
}

StatusOr<TetMesh> make_sphere_mesh(const SphereMeshOptions& options) {
  if (Status s = validate(options); !s.ok()) return s;
  // Meshing runs in normalised units, radius in [1, 2): TetGen's predicates
  // and volume bound are then independent of the unit. TetGen 1.5 fails on
  // absurd coordinates (radius 1e300: orient3d/insphere products overflow to
  // inf, an assertion in locate(); radius 1e-100: they underflow to 0, every
  // point looks coplanar and TetGen crashes freeing its pools), so the range
  // is also bounded by validate(). `scale` is a power of two: every step below
  // commutes exactly with it, and the mesh equals, bit for bit, the one made
  // directly in metres.
  const double scale = std::ldexp(1.0, std::ilogb(options.radius_m));
  const double radius = options.radius_m / scale;
  const double nucleus_radius = options.nucleus_radius_m / scale;
  const double target = options.target_vertex_count;
  const bool with_nucleus = options.nucleus_radius_m > 0.0;

  const GeodesicSize size = geodesic_size(target);
  const int frequency = size.frequency;
  const double volume_scale = size.volume_scale;
  auto surface_count = [](int f) { return 10.0 * f * f + 2.0; };
  std::vector<SurfaceMesh> surfaces;
  surfaces.push_back(make_geodesic_sphere(frequency, radius));
  const double spacing = mean_edge_length(surfaces[0]);
  if (with_nucleus) {
    // A shell thinner than half a mesh spacing cannot hold proper tets (and
    // the two polyhedra would intersect); a nucleus smaller than that is not
    // resolved and makes TetGen grade the mesh far past the vertex target.
    if (nucleus_radius < 0.5 * spacing || radius - nucleus_radius < 0.5 * spacing) {
      return invalid_argument("nucleus_radius_m must be in [h/2, radius_m - h/2] = [" +
                              number_text(0.5 * spacing * scale, 6) + ", " +
                              number_text((radius - 0.5 * spacing) * scale, 6) +
                              "] for target_vertex_count " + std::to_string(options.target_vertex_count) +
                              " (mesh spacing h = " + number_text(spacing * scale, 6) + "); got " +
                              number_text(options.nucleus_radius_m, 6));
    }
    const int nucleus_frequency =
        std::max(2, static_cast<int>(std::lround(frequency * nucleus_radius / radius)));
    surfaces.push_back(make_geodesic_sphere(nucleus_frequency, nucleus_radius));
  }

  const double outer_surface_count = surface_count(frequency);
  const double interior_target = target - outer_surface_count;
  double max_volume = kUniformVolumeFactor * spacing * spacing * spacing * volume_scale;
  StatusOr<TetMesh> best = Status(StatusCode::kInternal, "no mesh");
  double best_error = 1e300;
  double best_volume = max_volume;
  // Bracket of volume bounds that gave too many (too_fine) and too few
  // (too_coarse) vertices; the count is monotone but not continuous in the
  // bound (TetGen's refinement can jump), so once bracketed we bisect.
  double too_fine = 0.0;
  double too_coarse = 0.0;
  for (int attempt = 0; attempt < 10; ++attempt) {
    StatusOr<TetMesh> mesh =
        tetrahedralize_spheres(surfaces, max_volume, radius, nucleus_radius, scale, options);
    if (!mesh.ok()) return mesh.status();
    const double count = static_cast<double>(mesh->num_vertices());
    const double error = std::abs(count - target) / target;
    if (error < best_error) {
      best_error = error;
      best = std::move(mesh);
      best_volume = max_volume;
    }
    if (error < 0.03) break;
    (count > target ? too_fine : too_coarse) = max_volume;
    if (too_fine > 0.0 && too_coarse > 0.0) {
      max_volume = std::sqrt(too_fine * too_coarse);
    } else {
      // Interior vertices scale like 1 / max volume.
      max_volume *= std::max(1.0, count - outer_surface_count) / interior_target;
    }
  }
  // The last steps of either mesh: the sliver removal, metres, and the
  // locality order (TetGen's numbering is scattered, vertex_order.h; every
  // later pass streams the mesh in this order). The order comes last so that
  // the geometry is that of TetGen's numbering: the sliver removal visits the
  // tets in order.
  auto finish = [&](TetMesh& m) {
    remove_slivers(m, options.min_dihedral_deg, options.max_radius_edge_ratio, radius, nucleus_radius);
    for (double& x : m.positions_m) x *= scale;
    order_for_locality(m);
  };
  const double pole_spacing = options.pole_grading.pole_spacing_m / scale;
  if (pole_spacing > 0.0 && pole_spacing < spacing) {
    // The graded ring surface with the uniform mesh's bulk spacing and the
    // interior volume bound that met the vertex target: TetGen's radius-edge refinement grades the
    // interior from the small pole triangles.
    surfaces[0] = make_pole_graded_sphere_surface(radius, pole_spacing, spacing, options.pole_grading.growth,
                                                  options.pole_grading.ring_jitter);
    const std::size_t surface_vertices = surfaces[0].points.size() / 3;
    // A graded mesh holds 2-4 times its surface vertices: refuse before
    // TetGen runs what cannot stay within the vertex bound.
    if (surface_vertices > static_cast<std::size_t>(kMaxVertexCount) / 2) {
      return invalid_argument(
          "pole_grading.pole_spacing_m = " + number_text(options.pole_grading.pole_spacing_m, 6) +
          " m with growth " + number_text(options.pole_grading.growth, 6) + " needs " +
          std::to_string(surface_vertices) +
          " surface vertices: too fine (raise the pole spacing or the growth)");
    }
    // The interior follows the same sizing, the cone h_p + g |x - pole| of
    // the distance from the nearer pole, evaluated at each tet's
    // circumcentre: without it TetGen's radius-edge refinement coarsens
    // within a few layers below the fine surface, and the contact's stress
    // field (depth ~ the contact radius) lay in coarse, stiff linear tets
    // (+7 % on the colloidal probe at 4.5 um).
    const double growth = options.pole_grading.growth;
    Sizing sizing;
    sizing.edge_length = [&](const double* x) {
      const double to_pole =
          std::sqrt(x[0] * x[0] + x[1] * x[1] + (std::abs(x[2]) - radius) * (std::abs(x[2]) - radius));
      return std::min(spacing, pole_spacing + growth * to_pole);
    };
    StatusOr<TetMesh> graded =
        tetrahedralize_spheres(surfaces, best_volume, radius, nucleus_radius, scale, options, sizing);
    if (!graded.ok()) return graded.status();
    if (graded->num_vertices() > static_cast<std::size_t>(kMaxVertexCount)) {
      return invalid_argument(
          "pole_grading.pole_spacing_m = " + number_text(options.pole_grading.pole_spacing_m, 6) +
          " m gives " + std::to_string(graded->num_vertices()) + " vertices, more than " +
          std::to_string(kMaxVertexCount));
    }
    finish(*graded);
    return graded;
  }
  finish(best.value());
  return best;
}

}  // namespace cellflow::mesh
