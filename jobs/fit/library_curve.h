// Curves of the server's library (proto FitLibraryCurve) as the store keeps
// them: built from the force samples a worker reported for a library child
// job (a compression or indentation scene at the library's reference cell),
// and checked both when built and when read back from the database. Worker
// reports are hostile input: a curve that fails a check is not stored (the
// fit then simulates it itself). Protobuf and core only: the SQLite store
// links it.
#pragma once

#include <string>
#include <vector>

#include "cellflow/v1/service.pb.h"
#include "cellflow/v1/spec.pb.h"
#include "physics/core/status.h"

namespace cellflow::jobs {

// Bounds of one stored curve: the library's load points are at most 200
// (FitLibraryNumerics), a scene's at most 10,000.
inline constexpr int kMaxLibraryCurvePoints = 10000;
inline constexpr std::size_t kMaxLibraryKeyBytes = 4096;
inline constexpr std::size_t kMaxLibraryFailureBytes = 4096;
// f = F / (E R^2) of a sphere at deformation 0.9 is of order 10; anything
// beyond this bound is not a force of the scene.
inline constexpr double kMaxLibraryForceScaled = 1e3;
inline constexpr double kMaxLibraryDeformation = 0.9;

// The curve of a library child: sample i (sorted by index, indices 0, 1, ...
// without a gap, at most the child's load points) gives eps = its
// deformation and f = force_n / (E R^2) with E and R of the child's cell.
// `failure`: the child's reason when it failed part-way (empty if it
// succeeded: then every load point must be there). INVALID_ARGUMENT naming the sample when a check fails.
StatusOr<v1::FitLibraryCurve> library_curve_from_samples(const std::string& key, const v1::JobSpec& child,
                                                         std::vector<v1::ForceSample> samples,
                                                         const std::string& failure);

// Key and failure bounded, w in [0, 1], 1..kMaxLibraryCurvePoints points of
// equal-length arrays, eps finite, increasing, in (0, kMaxLibraryDeformation],
// f finite in [0, kMaxLibraryForceScaled].
Status check_library_curve(const v1::FitLibraryCurve& curve);

}  // namespace cellflow::jobs
