// A study's expansion (jobs/study): points in GRID and ZIP order, values set
// at JSON paths and parsed again strictly, and refusals that name the field
// (study.base, study.axes[i].path, study.axes[i].values[k]).
#include "jobs/study/study.h"

#include <gtest/gtest.h>

namespace cellflow::jobs {
namespace {

v1::JobSpec compression_base() {
  v1::JobSpec spec;
  spec.set_name("base");
  auto* c = spec.mutable_compression();
  c->mutable_cell()->set_radius_m(5e-6);
  c->set_max_deformation(0.2);
  return spec;
}

v1::StudySpec study_of(const v1::JobSpec& base) {
  v1::StudySpec study;
  *study.mutable_base() = base;
  return study;
}

void add_axis(v1::StudySpec& study, const std::string& path, std::vector<std::string> values) {
  auto* axis = study.add_axes();
  axis->set_path(path);
  for (auto& v : values) axis->add_values(v);
}

TEST(StudyExpansion, GridVariesTheLastAxisFastest) {
  v1::StudySpec study = study_of(compression_base());
  add_axis(study, "compression.cell.material.youngsModulusPa", {"100", "200"});
  add_axis(study, "compression.maxDeformation", {"0.1", "0.2", "0.3"});
  auto points = expand_study(study);
  ASSERT_TRUE(points.ok()) << points.status().to_string();
  ASSERT_EQ(points->size(), 6u);
  const double e[] = {100, 100, 100, 200, 200, 200};
  const double d[] = {0.1, 0.2, 0.3, 0.1, 0.2, 0.3};
  for (int p = 0; p < 6; ++p) {
    const auto& c = (*points)[p].spec.compression();
    EXPECT_EQ(c.cell().material().youngs_modulus_pa(), e[p]) << p;
    EXPECT_EQ(c.max_deformation(), d[p]) << p;
    EXPECT_EQ(c.cell().radius_m(), 5e-6) << "the base's other fields stay";
    EXPECT_EQ((*points)[p].value_index, (std::vector<int>{p / 3, p % 3}));
  }
  EXPECT_EQ((*points)[4].label,
            "compression.cell.material.youngsModulusPa=200, compression.maxDeformation=0.2");
}

TEST(StudyExpansion, ZipTakesAxesTogetherAndNeedsEqualLengths) {
  v1::StudySpec study = study_of(compression_base());
  study.set_combination(v1::StudySpec::ZIP);
  add_axis(study, "compression.cell.material.youngsModulusPa", {"100", "200", "300"});
  add_axis(study, "compression.load_points", {"5", "6", "7"});  // the proto name works too
  auto points = expand_study(study);
  ASSERT_TRUE(points.ok()) << points.status().to_string();
  ASSERT_EQ(points->size(), 3u);
  EXPECT_EQ((*points)[2].spec.compression().cell().material().youngs_modulus_pa(), 300.0);
  EXPECT_EQ((*points)[2].spec.compression().load_points(), 7);
  add_axis(study, "compression.cell.radiusM", {"1e-6", "2e-6"});
  auto refused = expand_study(study);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(refused.status().message().find("study.axes[2].values: 2 values, axis 0 has 3"),
            std::string::npos)
      << refused.status().message();
}

TEST(StudyExpansion, EnumAndMessageValuesAreJson) {
  v1::StudySpec study = study_of(compression_base());
  add_axis(study, "compression.numerics.volumetricTerm",
           {"\"VOLUMETRIC_TERM_PER_TET\"", "\"VOLUMETRIC_TERM_NODAL_AVERAGE\""});
  auto points = expand_study(study);
  ASSERT_TRUE(points.ok()) << points.status().to_string();
  EXPECT_EQ((*points)[0].spec.compression().numerics().volumetric_term(), v1::VOLUMETRIC_TERM_PER_TET);
}

TEST(StudyExpansion, UnknownPathNamesTheAxisPath) {
  v1::StudySpec study = study_of(compression_base());
  add_axis(study, "compression.cell.material.youngsModulus", {"100"});
  auto refused = expand_study(study);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument);
  const std::string& m = refused.status().message();
  EXPECT_EQ(m.rfind("study.axes[0].path: ", 0), 0u) << m;
  EXPECT_NE(m.find("has no field \"youngsModulus\""), std::string::npos) << m;
  EXPECT_NE(m.find("youngsModulusPa"), std::string::npos) << "the known fields are listed: " << m;

  // Another scene than the base's, a scalar on the way, a nested study.
  for (const char* path : {"shearFlow.capillaryNumber", "compression.maxDeformation.x", "study.base"}) {
    v1::StudySpec s = study_of(compression_base());
    add_axis(s, path, {"1"});
    auto r = expand_study(s);
    ASSERT_FALSE(r.ok()) << path;
    EXPECT_EQ(r.status().message().rfind("study.axes[0].path: ", 0), 0u) << r.status().message();
  }
}

TEST(StudyExpansion, ValueOfTheWrongTypeNamesTheValue) {
  v1::StudySpec study = study_of(compression_base());
  add_axis(study, "compression.maxDeformation", {"0.1", "0.2"});
  add_axis(study, "compression.loadPoints", {"5", "\"many\"", "7"});
  auto refused = expand_study(study);
  ASSERT_FALSE(refused.ok());
  const std::string& m = refused.status().message();
  EXPECT_EQ(m.rfind("study.axes[1].values[1]: \"many\" does not fit compression.loadPoints", 0), 0u) << m;

  v1::StudySpec not_json = study_of(compression_base());
  add_axis(not_json, "compression.maxDeformation", {"0.1", "zero point two"});
  auto r = expand_study(not_json);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().message().rfind("study.axes[0].values[1]: ", 0), 0u) << r.status().message();
  EXPECT_NE(r.status().message().find("not a JSON value"), std::string::npos);
}

TEST(StudyExpansion, NestedStudiesAndBasesWithoutSceneAreRefused) {
  v1::StudySpec inner = study_of(compression_base());
  add_axis(inner, "compression.maxDeformation", {"0.1"});
  v1::JobSpec nested;
  *nested.mutable_study() = inner;
  v1::StudySpec outer = study_of(nested);
  add_axis(outer, "name", {"\"x\""});
  auto refused = expand_study(outer);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().message().rfind("study.base: ", 0), 0u) << refused.status().message();
  EXPECT_NE(refused.status().message().find("nested"), std::string::npos);

  v1::StudySpec empty;
  add_axis(empty, "name", {"\"x\""});
  auto no_scene = expand_study(empty);
  ASSERT_FALSE(no_scene.ok());
  EXPECT_EQ(no_scene.status().message().rfind("study.base: ", 0), 0u);
}

TEST(StudyExpansion, PointLimitIsCheckedBeforeExpanding) {
  v1::StudySpec study = study_of(compression_base());
  std::vector<std::string> hundred;
  for (int i = 0; i < 100; ++i) hundred.push_back(std::to_string(0.001 * (i + 1)));
  add_axis(study, "compression.maxDeformation", hundred);
  add_axis(study, "compression.cell.radiusM", hundred);
  auto counted = count_study_points(study);
  ASSERT_TRUE(counted.ok());
  EXPECT_EQ(*counted, 10000);  // exactly the limit
  add_axis(study, "compression.loadPoints", {"5", "6"});
  auto refused = expand_study(study);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("at most " + std::to_string(kMaxStudyPoints)), std::string::npos)
      << refused.status().message();
  // No axes, an empty axis, a path swept twice.
  v1::StudySpec none = study_of(compression_base());
  EXPECT_FALSE(expand_study(none).ok());
  v1::StudySpec twice = study_of(compression_base());
  add_axis(twice, "compression.maxDeformation", {"0.1"});
  add_axis(twice, "compression.maxDeformation", {"0.2"});
  auto dup = expand_study(twice);
  ASSERT_FALSE(dup.ok());
  EXPECT_EQ(dup.status().message().rfind("study.axes[1].path: ", 0), 0u);
}

TEST(StudyExpansion, SetSpecFieldCreatesMissingMessagesAndNamesItsArguments) {
  v1::JobSpec spec = compression_base();
  auto set = set_spec_field(spec, "compression.numerics.residualTolerance", "1e-8");
  ASSERT_TRUE(set.ok()) << set.status().to_string();
  EXPECT_EQ(set->compression().numerics().residual_tolerance(), 1e-8);
  auto bad = set_spec_field(spec, "compression.nope", "1", "--set", "--set value");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().message().rfind("--set: ", 0), 0u);
}

v1::JobSpec suspension_base() {
  v1::JobSpec spec;
  auto* s = spec.mutable_suspension();
  auto* first = s->add_cells();
  first->mutable_cell()->set_radius_m(6e-6);
  first->set_volume_fraction(0.1);
  auto* second = s->add_cells();
  second->mutable_cell()->set_radius_m(4e-6);
  second->set_count(2);
  s->set_capillary_number(0.1);
  return spec;
}

TEST(StudyExpansion, AnElementOfAListIsReachedByItsIndex) {
  v1::StudySpec study = study_of(suspension_base());
  add_axis(study, "suspension.cells[0].volumeFraction", {"0.11", "0.22"});
  add_axis(study, "suspension.cells[1].cell.radiusM", {"3e-6"});
  auto points = expand_study(study);
  ASSERT_TRUE(points.ok()) << points.status().to_string();
  ASSERT_EQ(points->size(), 2u);
  for (int p = 0; p < 2; ++p) {
    const auto& s = (*points)[static_cast<std::size_t>(p)].spec.suspension();
    ASSERT_EQ(s.cells_size(), 2);  // elements are changed in place, none added
    EXPECT_DOUBLE_EQ(s.cells(0).volume_fraction(), p == 0 ? 0.11 : 0.22);
    EXPECT_DOUBLE_EQ(s.cells(0).cell().radius_m(), 6e-6);
    EXPECT_DOUBLE_EQ(s.cells(1).cell().radius_m(), 3e-6);
    EXPECT_EQ(s.cells(1).count(), 2);
  }
  // A whole element can be set too.
  auto whole = set_spec_field(suspension_base(), "suspension.cells[1]", R"({"count": 5})");
  ASSERT_TRUE(whole.ok()) << whole.status().to_string();
  EXPECT_EQ(whole->suspension().cells(1).count(), 5);
  EXPECT_FALSE(whole->suspension().cells(1).has_cell());
  EXPECT_DOUBLE_EQ(whole->suspension().cells(0).volume_fraction(), 0.1);
}

TEST(StudyExpansion, BadIndicesAreRefusedNamingThePath) {
  const v1::JobSpec base = suspension_base();
  for (const char* path :
       {"suspension.cells[2].count", "suspension.cells[-1].count", "suspension.cells[x].count",
        "suspension.cells[0", "suspension.cells0].count", "suspension.cells[1234567].count",
        "suspension.cells.count", "suspension.capillaryNumber[0]", "suspension.cells[0].placements[0].xM"}) {
    auto set = set_spec_field(base, path, "1", "study.axes[0].path");
    ASSERT_FALSE(set.ok()) << path;
    EXPECT_NE(set.status().message().find("study.axes[0].path"), std::string::npos) << set.status().message();
    EXPECT_NE(set.status().message().find(path), std::string::npos) << set.status().message();
  }
}

TEST(StudyExpansion, ValueListsSplitAtTopLevelCommas) {
  EXPECT_EQ(split_value_list("1,2.5,[3,4],\"a,b\",{\"x\":1,\"y\":2}"),
            (std::vector<std::string>{"1", "2.5", "[3,4]", "\"a,b\"", "{\"x\":1,\"y\":2}"}));
  EXPECT_EQ(value_text_as_json("PER_TET"), "\"PER_TET\"");
  EXPECT_EQ(value_text_as_json("0.05"), "0.05");
  EXPECT_EQ(value_text_as_json("\"x\""), "\"x\"");
}

}  // namespace
}  // namespace cellflow::jobs
