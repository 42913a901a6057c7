#include "jobs/registry.h"

#include <string>

#include "jobs/fit/fit_job.h"
#include "jobs/quasi_static/quasi_static_job.h"
#include "jobs/shear_flow/shear_flow_job.h"

namespace cellflow::jobs {
namespace {

// The scenes, one line each: the spec's oneof case, its field name, and the
// function that converts and validates it.
constexpr SceneEntry kScenes[] = {
    {v1::JobSpec::kCompression, "compression", &prepare_compression},
    {v1::JobSpec::kIndentation, "indentation", &prepare_indentation},
    {v1::JobSpec::kShearFlow, "shear_flow", &prepare_shear_flow},
    {v1::JobSpec::kFit, "fit", &prepare_fit},
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
  if (entry == nullptr) {
    std::string names;
    for (const SceneEntry& e : kScenes) names += (names.empty() ? "" : ", ") + std::string(e.name);
    return invalid_argument("scene: one of " + names + " must be set");
  }
  conversions_.fetch_add(1, std::memory_order_relaxed);
  return entry->prepare(spec);
}

}  // namespace cellflow::jobs
