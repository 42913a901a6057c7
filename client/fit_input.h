// The measured curves of `cellflow fit`, read and preprocessed on the client
// (the server never reads a file a request names): each file through io/afm
// (read_force_curve), its approach segment, the tip position (height minus
// deflection; the height when the deflection is unknown), the baseline and a
// first contact estimate (baseline deviation), the force with the baseline
// subtracted, and the indentation from that estimate, as a v1::FitCurve with
// the samples from 0.1 deformation (0.2 R) before the estimate on, and the
// force noise (the baseline's RMS residual, at least a third of the deepest
// negative excursion of the sent samples before the contact estimate).
//
// A tip position derived from height and deflection that is not increasing
// (the noise of both) is sorted and ties are dropped; a position channel the file gives
// directly (tip position, indentation, or height without deflection) must
// increase: else the error names the sample. Every error names the file.
//
// With FitInputOptions::contact_at_zero the curve starts at contact (a
// finite-element reference, or data already processed): position 0 is the
// contact point and the force has no offset, so there is no free part to fit
// a baseline on. The curve is sent as it is: indentation = the position
// column, force as read, contact estimate 0, force noise 0 (the fit's relative
// floor); the fit still refines the contact within its contact window.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "cellflow/v1/spec.pb.h"
#include "physics/core/status.h"

namespace cellflow::client {

struct FitInputOptions {
  std::optional<double> spring_constant_n_per_m;  // override the file's calibration
  std::optional<double> sensitivity_m_per_v;
  bool contact_at_zero = false;  // skip baseline and contact estimation (see above)
};

struct FitInputCurve {
  std::string file;
  v1::FitCurve curve;
  double contact_estimate_m = 0.0;   // tip position of the contact estimate, in the file's coordinates
  std::vector<int> approach_sample;  // per sent sample: its index in the file's approach segment
};

// `radius_m` > 0: the cell radius (the pre-contact margin is 0.1 of its diameter).
StatusOr<FitInputCurve> read_fit_curve(const std::string& path, double radius_m,
                                       const FitInputOptions& options);

// The client's check before submitting: jobs::to_fit_plan over the spec with
// an error that names the file and the approach sample (not fit.curves[i].force_n[j]).
Status check_fit_spec(const v1::FitSpec& spec, const std::vector<FitInputCurve>& inputs);

}  // namespace cellflow::client
