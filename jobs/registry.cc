#include "jobs/registry.h"

#include <string>

#include "jobs/fit/fit_job.h"
#include "jobs/quasi_static/quasi_static_job.h"
#include "jobs/shear_flow/shear_flow_job.h"
#include "jobs/suspension/suspension_job.h"

namespace cellflow::jobs {
namespace {

// The scenes, one line each: the spec's oneof case, its field name, and the
// function that converts and validates it.
constexpr SceneEntry kScenes[] = {
    {v1::JobSpec::kCompression, "compression", &prepare_compression},
    {v1::JobSpec::kIndentation, "indentation", &prepare_indentation},
    {v1::JobSpec::kShearFlow, "shear_flow", &prepare_shear_flow},
    {v1::JobSpec::kFit, "fit", &prepare_fit},
    {v1::JobSpec::kSuspension, "suspension", &prepare_suspension},
};

}  // namespace

std::span<const SceneEntry> registered_scenes() {
  return kScenes;
}

const SceneEntry* find_scene(const v1::JobSpec& spec) {
  for (const SceneEntry& entry : kScenes) {
    if (entry.scene_case == spec.scene_case()) return &entry;
  }
  return nullptr;
}

StatusOr<std::unique_ptr<PreparedJob>> SceneRegistry::prepare(const v1::JobSpec& spec) const {
  const SceneEntry* entry = find_scene(spec);
  if (spec.has_study()) {
    return invalid_argument(
        "study: a study is expanded by the server into one job per point (cellflow sweep); a worker or "
        "cellflow-run runs one scene");
  }
  if (entry == nullptr) {
    std::string names;
    for (const SceneEntry& e : kScenes) names += (names.empty() ? "" : ", ") + std::string(e.name);
    return invalid_argument("scene: one of " + names + " must be set");
  }
  // An uploaded mesh's bytes are filled in by the server or the worker that
  // fetched them; without them the spec cannot run (and must not fall back to a sphere).
  v1::JobSpec copy = spec;  // scene_cells hands out mutable cells; nothing is changed
  for (const SceneCell& scene_cell : scene_cells(copy)) {
    if (!scene_cell.cell->mesh_sha256().empty() && scene_cell.cell->mesh_bytes().empty()) {
      return invalid_argument(scene_cell.field +
                              ".mesh_sha256: an uploaded mesh runs through the service, which "
                              "fetches its bytes (a local run reads cell.mesh_file)");
    }
  }
  conversions_.fetch_add(1, std::memory_order_relaxed);
  return entry->prepare(spec);
}

}  // namespace cellflow::jobs
