// The scene registry: the one place that knows which scenes exist. The
// server, the worker and cellflow-run look a job's scene up here, convert and
// validate its spec once (prepare), and run what prepare returned; the client
// names a scene through jobs/spec_json.h. A new scene is a folder under jobs/
// (conversion, run, recorder, result schema) and one line in registry.cc.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "cellflow/v1/spec.pb.h"
#include "jobs/scene.h"
#include "jobs/spec_json.h"  // scene_cells
#include "physics/core/status.h"

namespace cellflow::jobs {

// Every registered scene, in the order of the spec's oneof.
std::span<const SceneEntry> registered_scenes();

// The entry of the scene `spec` names, or nullptr.
const SceneEntry* find_scene(const v1::JobSpec& spec);

// A registry instance per process component (the server's job service, a
// worker): it prepares jobs and counts how often it converted a spec, so a
// test can check that each job is converted once.
class SceneRegistry {
 public:
  // Converts and validates `spec`; INVALID_ARGUMENT names the field path
  // (also when no scene is set).
  StatusOr<std::unique_ptr<PreparedJob>> prepare(const v1::JobSpec& spec) const;

  // Spec conversions made by prepare() so far.
  std::int64_t conversions() const { return conversions_.load(std::memory_order_relaxed); }

 private:
  mutable std::atomic<std::int64_t> conversions_{0};
};

}  // namespace cellflow::jobs
