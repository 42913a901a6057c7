// Status values returned across layers instead of exceptions (LevelDB status.h
// style). A physics failure is a result: it carries a code and a message that
// names the field, the load step or the time step and the cause.
#pragma once

#include <cassert>
#include <optional>
#include <string>
#include <utility>

namespace cellflow {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,     // a spec field outside its allowed range
  kNotFound,            // a file or record that does not exist
  kFailedPrecondition,  // e.g. a mesh with inverted tetrahedra
  kResourceExhausted,   // memory estimate over the configured limit
  kNumericalFailure,    // J <= 0, NaN, non-convergence, instability
  kCancelled,           // stopped on request
  kInternal,
};

const char* status_code_name(StatusCode code);

class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status ok_status() { return {}; }
  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  std::string to_string() const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

inline Status invalid_argument(std::string message) {
  return {StatusCode::kInvalidArgument, std::move(message)};
}
inline Status numerical_failure(std::string message) {
  return {StatusCode::kNumericalFailure, std::move(message)};
}

// A value or the Status saying why there is none.
template <class T>
class [[nodiscard]] StatusOr {
 public:
  StatusOr(T value) : value_(std::move(value)) {}  // NOLINT(google-explicit-constructor)
  StatusOr(Status status) : status_(std::move(status)) {  // NOLINT(google-explicit-constructor)
    assert(!status_.ok() && "StatusOr needs a value or a non-ok status");
  }

  bool ok() const { return value_.has_value(); }
  const Status& status() const { return status_; }
  T& value() & { return *value_; }
  const T& value() const& { return *value_; }
  T&& value() && { return std::move(*value_); }
  T* operator->() { return &*value_; }
  const T* operator->() const { return &*value_; }
  T& operator*() & { return *value_; }
  const T& operator*() const& { return *value_; }

 private:
  Status status_;
  std::optional<T> value_;
};

}  // namespace cellflow
