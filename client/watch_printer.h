// How `cellflow watch` shows a job's events: one plain line per event when
// the output is piped (stable key=value text for scripts), and on a terminal
// the samples as lines above a progress bar that is redrawn in place.
#pragma once

#include <cstdio>
#include <string>

#include "cellflow/v1/service.pb.h"

namespace cellflow::client {

// One line, no newline: "seq=7 attempt=1 sample index=3 deformation=...".
std::string event_line(const v1::JobEvent& event);

// "[########............]  40%  ETA 0:12  load point 16/40"
std::string progress_bar(double fraction, double remaining_s, const std::string& stage, int width = 30);

class WatchPrinter {
 public:
  WatchPrinter(std::FILE* out, bool terminal) : out_(out), terminal_(terminal) {}
  void print(const v1::JobEvent& event);
  // Ends the progress bar line on a terminal.
  void finish();
  // Watching a study of `count` children: the bar counts children done
  // (ChildUpdate events to a terminal state) instead of progress events.
  void set_child_count(int count) { child_count_ = count; }
  int children_done() const { return children_done_; }
  v1::Job::State last_state() const { return last_state_; }
  std::int64_t last_sequence() const { return last_sequence_; }

 private:
  void clear_bar();
  std::FILE* out_;
  bool terminal_;
  bool bar_shown_ = false;
  std::string bar_;
  v1::Job::State last_state_ = v1::Job::STATE_UNSPECIFIED;
  std::int64_t last_sequence_ = 0;
  int child_count_ = 0;
  int children_done_ = 0;
};

}  // namespace cellflow::client
