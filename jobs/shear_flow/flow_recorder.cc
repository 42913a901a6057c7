#include "jobs/shear_flow/flow_recorder.h"

#include <algorithm>
#include <cmath>

namespace cellflow::jobs {

std::int64_t FlowRecorderBase::step_of(double time_s) const {
  return setup_.time_step_s > 0.0 ? std::llround(time_s / setup_.time_step_s) : 0;
}

void FlowRecorderBase::write_flow_box() {
  io::H5mdBox box;
  box.periodic[0] = box.periodic[2] = true;
  box.has_edges = true;
  for (int d = 0; d < 3; ++d) box.edges_m[d] = setup_.box_m[d];
  keep(writer_->set_box("cell", box));
  keep(writer_->flush());
}

void FlowRecorderBase::write_stop(scenes::ShearFlowStop stop, const Status& status) {
  keep(writer_->write_string("/summary/stop", scenes::stop_name(stop)));
  if (!status.ok()) keep(writer_->write_string("/summary/status", status.to_string()));
}

Status FlowRecorderBase::close_with_warnings(const std::vector<std::string>& warnings) {
  std::string text;
  for (const std::string& w : warnings) text += (text.empty() ? "" : "\n") + w;
  if (!text.empty()) keep(writer_->write_string("/summary/warnings", text));
  keep(writer_->close());
  return status_;
}

double flow_transient_bytes(const scenes::ShearFlowSetup& setup) {
  const double nodes = static_cast<double>(setup.nx) * setup.ny * setup.nz;
  return nodes * 3.0 * 8.0;
}

double kept_snapshot_bytes(const scenes::ShearFlowNumerics& numerics, double vertices) {
  const double frames =
      numerics.snapshot_every_strain > 0.0 ? numerics.max_strain / numerics.snapshot_every_strain + 2.0 : 0.0;
  return std::min(frames * vertices * 3.0 * 8.0, static_cast<double>(scenes::kMaxCheckpointSnapshotBytes));
}

}  // namespace cellflow::jobs
