// The meshed elastic body of a cell: the mesh of CellParams (build_cell_mesh),
// centred at the origin, its per-region materials and the ElasticBody built on
// it (B = J^-1 and V0 per tet at the centred reference configuration). One
// function for every scene, so that the contact scenes and the flow scenes
// hold the same cell.
#pragma once

#include <array>
#include <string_view>

#include "physics/cell/cell_params.h"
#include "physics/core/status.h"
#include "physics/elastic/elastic_body.h"
#include "physics/elastic/material.h"
#include "physics/mesh/tet_mesh.h"

namespace cellflow::cell {

// Where the reference mesh is centred before the body is built (the body's
// reference configuration, and so its round-off, depends on it).
enum class Centring {
  kBoundingBox,     // the centre of the bounding box at the origin (contact scenes)
  kVolumeCentroid,  // the volume-weighted centroid at the origin (flow scenes)
};

struct CellBody {
  mesh::TetMesh mesh;  // centred at the origin; on_surface marked
  // Indexed by mesh::Region: cytoplasm, nucleus. Nucleus tets of a file
  // without nucleus parameters take the cytoplasm material.
  std::array<elastic::Material, 2> materials;
  elastic::ElasticBody body;
  std::array<double, 3> extent_m{};  // bounding-box size hi - lo of the reference mesh
  double reference_taylor_deformation =
      0.0;  // D of the mesh as meshed (paper eq. 13): the discretisation floor
};

// build_cell_mesh (errors carried through, field paths under field_prefix,
// e.g. "shear_flow.cell."), centring, then elastic::make_elastic_body with
// `volumetric` (errors prefixed with field_prefix less its trailing dot).
// `pole_grading`: the generated sphere's grading towards its poles.
// `element` kQuadraticTet adds a node per edge after the centring
// (mesh::add_mid_edge_nodes; the surface ones on the sphere through the
// edge's ends about the origin for a generated sphere, straight for a mesh
// file) and builds the quadratic body (volumetric must then be kPerTet).
StatusOr<CellBody> build_cell_body(const CellParams& cell, elastic::VolumetricTerm volumetric,
                                   std::string_view field_prefix = "cell.",
                                   Centring centring = Centring::kBoundingBox,
                                   const mesh::PoleGrading& pole_grading = {},
                                   elastic::Element element = elastic::Element::kLinearTet);

}  // namespace cellflow::cell
