#include "client/watch_printer.h"

#include <algorithm>
#include <cmath>

namespace cellflow::client {

namespace {

std::string format(const char* fmt, double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, fmt, value);
  return buffer;
}

std::string duration(double seconds) {
  if (seconds < 0) return "?";
  const long s = std::lround(seconds);
  char buffer[32];
  if (s >= 3600) {
    std::snprintf(buffer, sizeof buffer, "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
  } else {
    std::snprintf(buffer, sizeof buffer, "%ld:%02ld", s / 60, s % 60);
  }
  return buffer;
}

}  // namespace

std::string event_line(const v1::JobEvent& event) {
  std::string line =
      "seq=" + std::to_string(event.sequence()) + " attempt=" + std::to_string(event.attempt()) + " ";
  switch (event.kind_case()) {
    case v1::JobEvent::kStateChange: {
      const auto& c = event.state_change();
      line += "state " + v1::Job::State_Name(c.state());
      if (!c.worker_id().empty()) line += " worker=" + c.worker_id();
      if (!c.reason().empty()) line += " reason=\"" + c.reason() + "\"";
      break;
    }
    case v1::JobEvent::kProgress: {
      const auto& p = event.progress();
      line += "progress fraction=" + format("%.4f", p.fraction_done()) +
              " elapsed_s=" + format("%.2f", p.elapsed_s()) +
              " remaining_s=" + format("%.2f", p.estimated_remaining_s()) + " stage=\"" + p.stage() + "\"";
      break;
    }
    case v1::JobEvent::kForceSample: {
      const auto& s = event.force_sample();
      line +=
          "sample index=" + std::to_string(s.index()) + " deformation=" + format("%.6g", s.deformation()) +
          " displacement_m=" + format("%.6e", s.displacement_m()) +
          " force_n=" + format("%.6e", s.force_n()) + " hertz_force_n=" + format("%.6e", s.hertz_force_n()) +
          " taylor_deformation=" + format("%.6g", s.taylor_deformation());
      break;
    }
    case v1::JobEvent::kDeformationSample: {
      const auto& s = event.deformation_sample();
      line += "sample index=" + std::to_string(s.index()) + " time_s=" + format("%.6e", s.time_s()) +
              " strain=" + format("%.6g", s.strain()) +
              " taylor_deformation=" + format("%.6g", s.taylor_deformation()) +
              " inclination_rad=" + format("%.6g", s.inclination_rad()) +
              " net_strain=" + format("%.6g", s.net_strain()) +
              " tank_treading_per_s=" + format("%.6g", s.tank_treading_frequency_per_s());
      break;
    }
    case v1::JobEvent::kSuspensionSample: {
      const auto& s = event.suspension_sample();
      line += "sample index=" + std::to_string(s.index()) + " time_s=" + format("%.6e", s.time_s()) +
              " strain=" + format("%.6g", s.strain()) + " cells=" + std::to_string(s.cell_count()) +
              " mean_taylor_deformation=" + format("%.6g", s.mean_taylor_deformation()) +
              " mean_inclination_rad=" + format("%.6g", s.mean_inclination_rad()) +
              " relative_viscosity=" + format("%.6g", s.relative_viscosity()) +
              " contact_pairs=" + std::to_string(s.contact_pairs());
      if (s.average_taylor_deformation() != 0.0 || s.average_relative_viscosity() != 0.0) {
        line += " average_taylor_deformation=" + format("%.6g", s.average_taylor_deformation()) + "+-" +
                format("%.2g", s.average_taylor_deformation_error()) +
                " average_relative_viscosity=" + format("%.6g", s.average_relative_viscosity()) + "+-" +
                format("%.2g", s.average_relative_viscosity_error());
      }
      break;
    }
    case v1::JobEvent::kChildUpdate: {
      const auto& c = event.child_update();
      line += "child " + c.child_job_id() + " index=" + std::to_string(c.child_index()) + " state " +
              v1::Job::State_Name(c.state());
      if (!c.reason().empty()) line += " reason=\"" + c.reason() + "\"";
      break;
    }
    case v1::JobEvent::KIND_NOT_SET:
      line += "unknown";
      break;
  }
  return line;
}

std::string progress_bar(double fraction, double remaining_s, const std::string& stage, int width) {
  fraction = std::clamp(fraction, 0.0, 1.0);
  const int filled = static_cast<int>(std::lround(fraction * width));
  std::string bar = "[";
  bar.append(static_cast<std::size_t>(filled), '#');
  bar.append(static_cast<std::size_t>(width - filled), '.');
  bar += "] ";
  bar += format("%3.0f%%", 100.0 * fraction);
  bar += "  ETA ";
  bar += duration(remaining_s);
  if (!stage.empty()) {
    bar += "  ";
    bar += stage;
  }
  return bar;
}

void WatchPrinter::clear_bar() {
  if (terminal_ && bar_shown_) {
    std::fprintf(out_, "\r\033[2K");
    bar_shown_ = false;
  }
}

void WatchPrinter::print(const v1::JobEvent& event) {
  last_sequence_ = event.sequence();
  if (event.has_state_change()) last_state_ = event.state_change().state();
  if (terminal_ && event.has_progress()) {
    const auto& p = event.progress();
    bar_ = progress_bar(p.fraction_done(), p.estimated_remaining_s(), p.stage());
    clear_bar();
    std::fprintf(out_, "%s", bar_.c_str());
    bar_shown_ = true;
    std::fflush(out_);
    return;
  }
  // A study: the bar counts its children in a terminal state.
  if (event.has_child_update() && child_count_ > 0) {
    const v1::Job::State state = event.child_update().state();
    if (state == v1::Job::SUCCEEDED || state == v1::Job::FAILED || state == v1::Job::CANCELLED)
      ++children_done_;
    if (terminal_) {
      bar_ = progress_bar(
          static_cast<double>(children_done_) / child_count_, -1.0,
          "children " + std::to_string(children_done_) + "/" + std::to_string(child_count_) + " done");
    }
  }
  clear_bar();
  std::fprintf(out_, "%s\n", event_line(event).c_str());
  if (terminal_ && !bar_.empty() &&
      !(event.has_state_change() && event.state_change().state() >= v1::Job::SUCCEEDED)) {
    std::fprintf(out_, "%s", bar_.c_str());
    bar_shown_ = true;
  }
  std::fflush(out_);
}

void WatchPrinter::finish() {
  if (terminal_ && bar_shown_) std::fprintf(out_, "\n");
  bar_shown_ = false;
  std::fflush(out_);
}

}  // namespace cellflow::client
