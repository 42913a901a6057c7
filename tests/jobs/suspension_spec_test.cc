// The suspension job edge (jobs/suspension): proto SuspensionSpec -> the
// scene's parameters with the suspension's defaults, errors naming the proto
// field ("suspension.cells[1].viscosity_ratio"), the memory estimate counting
// every cell, the streamed sample bounded to 256 cells and the CSV columns.
#include "jobs/suspension/suspension_spec.h"

#include <gtest/gtest.h>

#include <string>

#include "jobs/registry.h"
#include "jobs/suspension/suspension_job.h"

namespace cellflow::jobs {
namespace {

// One kind of cell: R = 4 um, E = 50 Pa, `count` cells, coarse numerics.
v1::JobSpec suspension_of(int count) {
  v1::JobSpec spec;
  v1::SuspensionSpec* s = spec.mutable_suspension();
  v1::SuspendedCells* cells = s->add_cells();
  cells->mutable_cell()->set_radius_m(4e-6);
  cells->mutable_cell()->mutable_material()->set_youngs_modulus_pa(50.0);
  cells->set_count(count);
  s->set_capillary_number(0.1);
  return spec;
}

// The refusal of `spec` by the registry (what the server calls at submit).
std::string refusal(const v1::JobSpec& spec) {
  const SceneRegistry registry;
  auto prepared = registry.prepare(spec);
  EXPECT_FALSE(prepared.ok()) << "accepted:\n" << spec.DebugString();
  if (prepared.ok()) return "";
  EXPECT_EQ(prepared.status().code(), StatusCode::kInvalidArgument) << prepared.status().to_string();
  return prepared.status().message();
}

TEST(SuspensionSpec, UnsetFieldsTakeTheSuspensionDefaults) {
  const v1::JobSpec spec = suspension_of(4);
  StatusOr<scenes::SuspensionParams> p = convert(spec.suspension());
  ASSERT_TRUE(p.ok()) << p.status().to_string();
  ASSERT_EQ(p->kinds.size(), 1u);
  const scenes::SuspendedCellKind& kind = p->kinds[0];
  EXPECT_EQ(kind.cell.radius_m, 4e-6);
  EXPECT_EQ(kind.cell.target_vertex_count, 1000);  // not the single cell's 3000
  EXPECT_EQ(kind.viscosity_ratio, 1.0);
  EXPECT_EQ(kind.count, 4);
  EXPECT_EQ(kind.volume_fraction, 0.0);
  EXPECT_TRUE(kind.placements.empty());
  EXPECT_EQ(p->capillary_number, 0.1);
  EXPECT_EQ(p->shear_rate_per_s, 0.0);
  // The paper's box, no steady stop, 20 strain units (issue 15; suspension_numerics_defaults()).
  const scenes::ShearFlowNumerics& flow = p->numerics.flow;
  EXPECT_EQ(flow.box_x_radii, 5.0);
  EXPECT_EQ(flow.box_y_radii, 8.0);
  EXPECT_EQ(flow.box_z_radii, 4.0);
  EXPECT_EQ(flow.steady_tolerance, 0.0);
  EXPECT_EQ(flow.max_strain, 20.0);
  const scenes::SuspensionNumerics defaults = scenes::suspension_numerics_defaults();
  EXPECT_EQ(p->numerics.seed, defaults.seed);
  EXPECT_EQ(p->numerics.contact_range_dx, defaults.contact_range_dx);
  EXPECT_EQ(p->numerics.contact_strength, defaults.contact_strength);
  EXPECT_EQ(p->numerics.average_after_strain, defaults.average_after_strain);
  EXPECT_EQ(p->numerics.marking_every_steps, defaults.marking_every_steps);
  EXPECT_EQ(p->numerics.min_gap_dx, defaults.min_gap_dx);
  EXPECT_EQ(flow.cells_per_radius, defaults.flow.cells_per_radius);
}

TEST(SuspensionSpec, SetFieldsReachTheParameters) {
  v1::JobSpec spec = suspension_of(0);
  v1::SuspensionSpec* s = spec.mutable_suspension();
  s->set_shear_rate_per_s(25.0);
  v1::SuspendedCells* first = s->mutable_cells(0);
  first->set_viscosity_ratio(0.05);
  first->mutable_cell()->set_target_vertex_count(400);
  v1::CellPlacement* place = first->add_placements();
  place->set_x_m(1e-5);
  place->set_y_m(1.6e-5);
  place->set_z_m(8e-6);
  place->set_rotation_z_rad(0.3);
  v1::SuspendedCells* second = s->add_cells();
  *second->mutable_cell() = first->cell();
  second->set_volume_fraction(0.05);
  v1::SuspensionNumerics* n = s->mutable_numerics();
  n->set_seed(7);
  n->set_contact_range_dx(2.0);
  n->set_contact_strength(5.0);
  n->set_average_after_strain(3.0);
  n->set_target_standard_error(0.02);
  n->set_marking_every_steps(10);
  n->set_min_gap_dx(0.5);
  n->mutable_flow()->set_cells_per_radius(3.0);
  n->mutable_flow()->set_box_y_radii(10.0);
  n->mutable_flow()->set_ibm_kernel("peskin3");
  StatusOr<scenes::SuspensionParams> p = convert(*s);
  ASSERT_TRUE(p.ok()) << p.status().to_string();
  ASSERT_EQ(p->kinds.size(), 2u);
  EXPECT_EQ(p->shear_rate_per_s, 25.0);
  EXPECT_EQ(p->capillary_number, 0.0);
  EXPECT_EQ(p->kinds[0].viscosity_ratio, 0.05);
  EXPECT_EQ(p->kinds[0].cell.target_vertex_count, 400);
  ASSERT_EQ(p->kinds[0].placements.size(), 1u);
  EXPECT_EQ(p->kinds[0].placements[0].centre_m, (std::array<double, 3>{1e-5, 1.6e-5, 8e-6}));
  EXPECT_EQ(p->kinds[0].placements[0].rotation_rad, (std::array<double, 3>{0.0, 0.0, 0.3}));
  EXPECT_EQ(p->kinds[1].volume_fraction, 0.05);
  EXPECT_EQ(p->kinds[1].viscosity_ratio, 1.0);
  EXPECT_EQ(p->numerics.seed, 7u);
  EXPECT_EQ(p->numerics.contact_range_dx, 2.0);
  EXPECT_EQ(p->numerics.contact_strength, 5.0);
  EXPECT_EQ(p->numerics.average_after_strain, 3.0);
  EXPECT_EQ(p->numerics.target_standard_error, 0.02);
  EXPECT_EQ(p->numerics.marking_every_steps, 10);
  EXPECT_EQ(p->numerics.min_gap_dx, 0.5);
  EXPECT_EQ(p->numerics.flow.cells_per_radius, 3.0);
  EXPECT_EQ(p->numerics.flow.box_y_radii, 10.0);
  EXPECT_EQ(p->numerics.flow.box_x_radii, 5.0);  // unset: still the suspension's
  EXPECT_EQ(p->numerics.flow.ibm_kernel, ibm::Kernel::kPeskin3);
}

TEST(SuspensionSpec, MissingPiecesAreRefusedNamingTheField) {
  v1::JobSpec none;
  none.mutable_suspension()->set_capillary_number(0.1);
  EXPECT_NE(refusal(none).find("suspension.cells"), std::string::npos);

  v1::JobSpec no_cell = suspension_of(2);
  no_cell.mutable_suspension()->add_cells()->set_count(1);
  EXPECT_NE(refusal(no_cell).find("suspension.cells[1].cell must be set"), std::string::npos);

  v1::JobSpec too_many_kinds = suspension_of(1);
  for (int k = 0; k < kMaxSuspendedKinds; ++k)
    *too_many_kinds.mutable_suspension()->add_cells() = too_many_kinds.suspension().cells(0);
  EXPECT_NE(refusal(too_many_kinds).find("at most 64"), std::string::npos);

  v1::JobSpec no_drive = suspension_of(2);
  no_drive.mutable_suspension()->clear_capillary_number();
  EXPECT_NE(refusal(no_drive).find("suspension.shear_rate_per_s"), std::string::npos);

  v1::JobSpec zero_rate = suspension_of(2);
  zero_rate.mutable_suspension()->set_shear_rate_per_s(0.0);
  EXPECT_NE(refusal(zero_rate).find("suspension.shear_rate_per_s = 0"), std::string::npos);

  v1::JobSpec kernel = suspension_of(2);
  kernel.mutable_suspension()->mutable_numerics()->mutable_flow()->set_ibm_kernel("gauss");
  EXPECT_NE(refusal(kernel).find("suspension.numerics.flow.ibm_kernel"), std::string::npos);
}

TEST(SuspensionSpec, ZeroOrNegativeViscosityRatioIsRefusedNamingTheKind) {
  for (double lambda : {0.0, -1.0, -0.05}) {
    v1::JobSpec spec = suspension_of(2);
    *spec.mutable_suspension()->add_cells() = spec.suspension().cells(0);
    spec.mutable_suspension()->mutable_cells(1)->set_viscosity_ratio(lambda);
    const std::string message = refusal(spec);
    EXPECT_NE(message.find("suspension.cells[1].viscosity_ratio"), std::string::npos)
        << lambda << ": " << message;
    EXPECT_EQ(message.find("kinds["), std::string::npos) << message;  // the proto's name, not the struct's
  }
  // The near-elastic limit of the paper (lambda = 0.05) in the second kind is accepted.
  v1::JobSpec contrast = suspension_of(2);
  *contrast.mutable_suspension()->add_cells() = contrast.suspension().cells(0);
  contrast.mutable_suspension()->mutable_cells(1)->set_viscosity_ratio(0.05);
  const SceneRegistry registry;
  auto prepared = registry.prepare(contrast);
  ASSERT_TRUE(prepared.ok()) << prepared.status().to_string();
  StatusOr<scenes::PlannedSuspension> planned = plan(contrast.suspension());
  ASSERT_TRUE(planned.ok());
  EXPECT_EQ(planned->params().kinds[1].viscosity_ratio, 0.05);
  EXPECT_EQ(planned->cell_kinds(), (std::vector<int>{0, 0, 1, 1}));
}

TEST(SuspensionSpec, PlacementsThatOverlapOrLeaveTheBoxAreRefusedNamingThePlace) {
  // The default box: 5 x 8 x 4 R = 20 x 32 x 16 um.
  auto placed = [](std::initializer_list<std::array<double, 3>> centres) {
    v1::JobSpec spec = suspension_of(0);
    for (const auto& c : centres) {
      v1::CellPlacement* p = spec.mutable_suspension()->mutable_cells(0)->add_placements();
      p->set_x_m(c[0]);
      p->set_y_m(c[1]);
      p->set_z_m(c[2]);
    }
    return spec;
  };
  const SceneRegistry registry;
  EXPECT_TRUE(registry.prepare(placed({{5e-6, 10e-6, 8e-6}, {15e-6, 22e-6, 8e-6}})).ok());
  // Centres 2 um apart with R = 4 um.
  const std::string overlap = refusal(placed({{5e-6, 10e-6, 8e-6}, {7e-6, 10e-6, 8e-6}}));
  EXPECT_NE(overlap.find("suspension.cells[0].placements["), std::string::npos) << overlap;
  // Through the wall at y = 0, and beyond the top wall.
  const std::string wall = refusal(placed({{5e-6, 2e-6, 8e-6}}));
  EXPECT_NE(wall.find("suspension.cells[0].placements[0]"), std::string::npos) << wall;
  const std::string above = refusal(placed({{5e-6, 40e-6, 8e-6}}));
  EXPECT_NE(above.find("suspension.cells[0].placements[0]"), std::string::npos) << above;
}

TEST(SuspensionSpec, MoreCellsThanFitAreRefusedNamingTheField) {
  v1::JobSpec dense = suspension_of(0);
  dense.mutable_suspension()->mutable_cells(0)->set_volume_fraction(
      0.5);  // far above random close packing here
  const std::string fraction = refusal(dense);
  EXPECT_NE(fraction.find("suspension.cells[0].volume_fraction"), std::string::npos) << fraction;

  const std::string count = refusal(suspension_of(200));  // 200 spheres of volume 4.19 R^3 in 160 R^3
  EXPECT_NE(count.find("suspension.cells[0]"), std::string::npos) << count;
}

TEST(SuspensionJob, MemoryEstimateCountsEveryCell) {
  const SceneRegistry registry;
  auto four = registry.prepare(suspension_of(4));
  auto eight = registry.prepare(suspension_of(8));
  ASSERT_TRUE(four.ok()) << four.status().to_string();
  ASSERT_TRUE(eight.ok()) << eight.status().to_string();
  EXPECT_EQ((*four)->scene(), "suspension");
  StatusOr<scenes::PlannedSuspension> planned4 = plan(suspension_of(4).suspension());
  StatusOr<scenes::PlannedSuspension> planned8 = plan(suspension_of(8).suspension());
  ASSERT_TRUE(planned4.ok() && planned8.ok());
  EXPECT_EQ(planned4->setup().cell_count, 4);
  EXPECT_EQ(planned8->setup().cell_count, 8);
  EXPECT_GE((*four)->memory_bytes(), static_cast<std::int64_t>(planned4->setup().memory_bytes));
  // Four more cells of 1000 vertices: at least their positions and tetrahedra more.
  const std::int64_t per_cell_floor = 1000 * 3 * 8;
  EXPECT_GE((*eight)->memory_bytes() - (*four)->memory_bytes(), 4 * per_cell_floor);
  EXPECT_GE((*eight)->memory_bytes() - (*four)->memory_bytes(),
            static_cast<std::int64_t>(planned8->setup().memory_bytes - planned4->setup().memory_bytes));
  // Samples every 0.1 strain to 20: 200 and the final one.
  EXPECT_GE((*four)->max_sample_index(), 200);
}

TEST(SuspensionJob, StreamedSampleHoldsTheMeanAndAtMost256Cells) {
  scenes::SuspensionSample s;
  s.index = 3;
  s.time_s = 0.5;
  s.strain_units = 2.0;
  s.mean_taylor_deformation = 0.12;
  s.mean_inclination_deg = 30.0;
  s.relative_viscosity = 1.3;
  s.contact_pairs = 5;
  s.average_taylor_deformation = 0.11;
  s.average_taylor_deformation_error = 0.004;
  s.average_relative_viscosity = 1.31;
  s.average_relative_viscosity_error = 0.02;
  s.cells.resize(300);
  for (std::size_t i = 0; i < s.cells.size(); ++i) {
    s.cells[i].taylor_deformation = 0.001 * static_cast<double>(i);
    s.cells[i].inclination_deg = 45.0;
    s.cells[i].centroid_m = {1e-6 * static_cast<double>(i), 2e-6, 3e-6};
  }
  const v1::SuspensionSample m = suspension_sample_from(s);
  EXPECT_EQ(m.index(), 3);
  EXPECT_EQ(m.strain(), 2.0);
  EXPECT_EQ(m.cell_count(), 300);
  ASSERT_EQ(m.cells_size(), kMaxStreamedSuspensionCells);
  EXPECT_EQ(m.cells(255).cell(), 255);
  EXPECT_EQ(m.cells(255).taylor_deformation(), 0.001 * 255);
  EXPECT_DOUBLE_EQ(m.cells(10).inclination_rad(), 45.0 * std::numbers::pi / 180.0);
  ASSERT_EQ(m.cells(10).centroid_m_size(), 3);
  EXPECT_DOUBLE_EQ(m.cells(10).centroid_m(0), 1e-5);
  EXPECT_DOUBLE_EQ(m.mean_inclination_rad(), 30.0 * std::numbers::pi / 180.0);
  EXPECT_EQ(m.relative_viscosity(), 1.3);
  EXPECT_EQ(m.contact_pairs(), 5);
  EXPECT_EQ(m.average_relative_viscosity_error(), 0.02);

  const std::string header = suspension_csv_header();
  const std::string row = suspension_csv_row(s);
  EXPECT_EQ(std::count(header.begin(), header.end(), ','), std::count(row.begin(), row.end(), ','));
  EXPECT_EQ(row.substr(0, row.find(',', row.find(',', row.find(',', row.find(',') + 1) + 1) + 1)),
            "3,0.5,2,300");
}

TEST(SuspensionSpec, ProtoFieldNamesReplaceTheStructsKindNames) {
  const Status s = with_proto_field_names(
      invalid_argument("suspension.kinds[1].viscosity_ratio = 0 must lie in [0.01, 100]; "
                       "suspension.kinds[0].placements[2] overlaps"),
      "suspension.");
  EXPECT_EQ(s.message(),
            "suspension.cells[1].viscosity_ratio = 0 must lie in [0.01, 100]; "
            "suspension.cells[0].placements[2] overlaps");
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(with_proto_field_names(Status(), "suspension.").ok());
}

}  // namespace
}  // namespace cellflow::jobs
