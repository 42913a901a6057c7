#include "jobs/fit/fit_job.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <vector>

#include "io/h5md.h"
#include "jobs/common/result_file.h"
#include "jobs/fit/fit_library.h"
#include "jobs/fit/fit_spec.h"
#include "physics/calibration/fit.h"
#include "physics/calibration/models.h"
#include "physics/core/violations.h"

namespace cellflow::jobs {
namespace {

namespace cal = cellflow::calibration;
using json = nlohmann::json;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

json number(double v) {
  return std::isfinite(v) ? json(v) : json(nullptr);
}

json estimate_json(const cal::Estimate& e, double shift = 0.0) {
  return {{"value", number(e.value + shift)},   {"lower", number(e.lower + shift)},
          {"upper", number(e.upper + shift)},   {"lower_at_bound", e.lower_at_bound},
          {"upper_at_bound", e.upper_at_bound}, {"fixed", e.fixed}};
}

std::string interval_text(const cal::Estimate& e, double scale, const char* unit) {
  char buffer[160];
  if (e.fixed) {
    std::snprintf(buffer, sizeof buffer, "%.4g%s (fixed)", e.value * scale, unit);
  } else if (std::isfinite(e.lower)) {
    std::snprintf(buffer, sizeof buffer, "%.4g%s [%.4g, %.4g]", e.value * scale, unit, e.lower * scale,
                  e.upper * scale);
  } else {
    std::snprintf(buffer, sizeof buffer, "%.4g%s", e.value * scale, unit);
  }
  return buffer;
}

// The fit of a whole job: calibration's result (or the Hertz model's in the same shape).
struct JobFit {
  cal::FitResult result;
  int simulations_run = 0;
  int curves_loaded = 0;
  int server_curves = 0;      // curves the server attached to the spec
  int child_simulations = 0;  // library simulations the server ran as this fit's children
  std::string library_dir;
};

cal::Geometry geometry_of(const FitPlan& plan) {
  return plan.geometry == FitGeometryKind::kPlates ? cal::Geometry::kPlates : cal::Geometry::kProbe;
}

double hertz_force(const FitPlan& plan, const FitCurvePlan& c, double e, double indentation_m) {
  return plan.geometry == FitGeometryKind::kPlates
             ? cal::hertz_plates_force_n(e, plan.poisson_ratio, c.radius_m, indentation_m)
             : cal::hertz_probe_force_n(e, plan.poisson_ratio, c.radius_m, c.probe_radius_m, indentation_m);
}

std::vector<cal::MeasuredCurve> measured_curves(const FitPlan& plan) {
  std::vector<cal::MeasuredCurve> out;
  for (const FitCurvePlan& c : plan.curves) {
    cal::MeasuredCurve m;
    m.name = c.name;
    m.geometry = geometry_of(plan);
    m.radius_m = c.radius_m;
    m.probe_radius_m = c.probe_radius_m;
    m.indentation_m = c.indentation_m;
    m.force_n = c.force_n;
    m.force_noise_n = c.force_noise_n;
    out.push_back(std::move(m));
  }
  return out;
}

cal::FitOptions fit_options(const FitPlan& plan) {
  cal::FitOptions o;
  o.poisson_ratio = plan.poisson_ratio;
  o.mooney_rivlin_w = plan.mooney_rivlin_w;
  o.min_deformation = plan.min_deformation;
  o.max_deformation = plan.max_deformation;
  o.fit_contact_point = plan.fit_contact_point;
  o.contact_window_radii = plan.contact_window_radii;
  o.hertz_max_deformation = plan.hertz_max_deformation;
  o.per_curve = plan.per_curve;
  o.joint = plan.joint;
  o.numerics.target_vertex_count = plan.target_vertex_count;
  o.numerics.load_points = plan.load_points;
  o.numerics.max_deformation = plan.library_max_deformation;
  o.numerics.residual_tolerance = plan.residual_tolerance;
  return o;
}

// Weights of fit.cc's noise model: sigma = max(|F|, max(noise, 1 % max F)).
std::vector<double> weights_of(const FitCurvePlan& c) {
  double max_force = 0.0;
  for (double f : c.force_n) max_force = std::max(max_force, f);
  const double floor = std::max({c.force_noise_n, 0.01 * max_force, 1e-300});
  std::vector<double> w;
  for (double f : c.force_n) {
    const double s = std::max(std::abs(f), floor);
    w.push_back(1.0 / (s * s));
  }
  return w;
}

cal::Estimate free_estimate(double value) {
  cal::Estimate e;
  e.value = value;
  e.lower = e.upper = kNaN;
  return e;
}

// The Hertz model: per curve E and contact by the closed form and a contact search; joint E at those
// contacts.
StatusOr<cal::FitResult> fit_hertz(const FitPlan& plan) {
  cal::FitResult result;
  std::vector<double> all_shape, all_force, all_weight;
  std::vector<cal::CurvePart> parts;
  for (std::size_t ci = 0; ci < plan.curves.size(); ++ci) {
    const FitCurvePlan& c = plan.curves[ci];
    const std::vector<double> weight = weights_of(c);
    const double window = plan.fit_contact_point ? plan.contact_window_radii * c.radius_m : 0.0;
    auto shape = [&](double d) { return hertz_force(plan, c, 1.0, d); };
    StatusOr<cal::ContactFit> fit =
        cal::fit_contact_point(c.indentation_m, c.force_n, weight, shape, -window, window);
    if (!fit.ok()) {
      return invalid_argument("fit.curves[" + std::to_string(ci) + "] (" + c.name +
                              "): " + fit.status().message());
    }
    cal::CurvePart part;
    part.name = c.name;
    part.contact_offset_m = free_estimate(fit->contact_m);
    if (!plan.fit_contact_point) part.contact_offset_m.fixed = true;
    double s2 = 0.0;
    for (std::size_t i = 0; i < c.indentation_m.size(); ++i) {
      const double d = c.indentation_m[i] - fit->contact_m;
      part.points.push_back(i);
      part.deformation.push_back(d / (2.0 * c.radius_m));
      part.model_force_n.push_back(fit->youngs_modulus_pa * shape(d));
      const double r = (c.force_n[i] - part.model_force_n.back()) * std::sqrt(weight[i]);
      s2 += r * r;
      all_shape.push_back(shape(d));
      all_force.push_back(c.force_n[i]);
      all_weight.push_back(weight[i]);
    }
    part.rms_relative_residual = std::sqrt(s2 / static_cast<double>(c.indentation_m.size()));
    cal::ParameterFit pf;
    pf.youngs_modulus_pa = free_estimate(fit->youngs_modulus_pa);
    pf.mooney_rivlin_w.value = pf.mooney_rivlin_w.lower = pf.mooney_rivlin_w.upper = 1.0;
    pf.mooney_rivlin_w.fixed = true;
    pf.points = static_cast<int>(c.indentation_m.size());
    pf.parameters = plan.fit_contact_point ? 2 : 1;
    pf.objective = s2;
    pf.rms_relative_residual = part.rms_relative_residual;
    pf.hertz_youngs_modulus_pa = fit->youngs_modulus_pa;
    pf.hertz_points = fit->points_in_contact;
    pf.curves.push_back(part);
    parts.push_back(part);
    if (plan.per_curve) result.per_curve.push_back(std::move(pf));
  }
  if (plan.joint) {
    StatusOr<double> e = cal::closed_form_modulus(all_shape, all_force, all_weight);
    if (!e.ok()) return e.status();
    cal::ParameterFit pf;
    pf.youngs_modulus_pa = free_estimate(*e);
    pf.mooney_rivlin_w.value = pf.mooney_rivlin_w.lower = pf.mooney_rivlin_w.upper = 1.0;
    pf.mooney_rivlin_w.fixed = true;
    double s2 = 0.0;
    std::size_t k = 0;
    for (cal::CurvePart& part : parts) {
      for (double& f : part.model_force_n) {
        f = *e * all_shape[k];
        const double r = (all_force[k] - f) * std::sqrt(all_weight[k]);
        s2 += r * r;
        ++k;
      }
    }
    pf.curves = parts;
    pf.points = static_cast<int>(k);
    pf.parameters = 1 + (plan.fit_contact_point ? static_cast<int>(parts.size()) : 0);
    pf.objective = s2;
    pf.rms_relative_residual = std::sqrt(s2 / static_cast<double>(k));
    pf.hertz_youngs_modulus_pa = *e;
    pf.hertz_points = pf.points;
    result.joint = std::move(pf);
  }
  result.notes.push_back("model hertz: no scene simulations; no profile intervals");
  return result;
}

// Progress hooks of a run (both may be empty).
struct Hooks {
  std::function<void(double, const std::string&)> progress;
  std::function<bool()> should_stop;
};

StatusOr<JobFit> compute(const FitPlan& plan, const std::string& library_dir, int threads, const Hooks& hooks,
                         const v1::FitServerLibrary* server = nullptr) {
  JobFit out;
  out.library_dir = library_dir;
  auto progress = [&](double f, const std::string& stage) {
    if (hooks.progress) hooks.progress(f, stage);
  };
  if (plan.model == FitModelKind::kHertz) {
    progress(0.5, "fitting (Hertz model, no library)");
    StatusOr<cal::FitResult> r = fit_hertz(plan);
    if (!r.ok()) return r.status();
    out.result = std::move(*r);
    return out;
  }
  const cal::LibraryOptions lo = fit_library_options(threads);
  cal::CurveLibrary library(lo);
  StatusOr<int> loaded = library.load(library_dir);
  out.curves_loaded = loaded.ok() ? *loaded : 0;
  std::vector<std::string> notes;
  if (!loaded.ok() && loaded.status().code() != StatusCode::kNotFound) {
    notes.push_back("library not read: " + loaded.status().message());
  }
  // The server's curves (its child jobs' and earlier fits'), checked again here.
  if (server != nullptr) {
    out.child_simulations = std::max(0, server->child_simulations());
    for (const v1::FitLibraryCurve& c : server->curves()) {
      cal::LibraryCurve curve;
      curve.mooney_rivlin_w = c.mooney_rivlin_w();
      curve.deformation.assign(c.deformation().begin(), c.deformation().end());
      curve.force_scaled.assign(c.force_scaled().begin(), c.force_scaled().end());
      curve.failure = c.failure();
      if (Status s = library.insert(c.key(), std::move(curve)); s.ok()) {
        ++out.server_curves;
      } else {
        notes.push_back("server curve not used: " + s.message());
      }
    }
  }
  progress(0.0, "library " + library_dir + ": " + std::to_string(out.curves_loaded) + " curves loaded, " +
                    std::to_string(out.server_curves) + " from the server");

  // The curves the fit will ask for: every grid w (w free) or the one w, per
  // key, and the deepest deformation each key's curves must reach (as fit_curves computes it).
  const cal::FitOptions options = fit_options(plan);
  StatusOr<std::vector<FitLibraryKey>> library_keys = fit_library_keys(plan, lo);
  if (!library_keys.ok()) return library_keys.status();
  std::map<std::string, cal::CurveKey> keys;
  std::map<std::string, double> needed;
  for (const FitLibraryKey& k : *library_keys) {
    keys[k.text] = k.key;
    needed[k.text] = k.needed_max_deformation;
  }
  const std::vector<double> ws = fit_library_w(plan, lo);
  const int total = static_cast<int>(keys.size() * ws.size());
  int done = 0, simulated = 0;
  double cut_w = -1.0;  // the largest w whose curve ends before the needed deformation (w free)
  for (const auto& [text, key] : keys) {
    for (auto w = ws.rbegin(); w != ws.rend(); ++w) {  // from w = 1 down, as grid_interpolant uses them
      if (hooks.should_stop && hooks.should_stop()) return Status(StatusCode::kCancelled, "cancelled");
      const std::size_t size_before = library.size();
      const auto t0 = std::chrono::steady_clock::now();
      StatusOr<const cal::LibraryCurve*> c = library.curve(key, *w);  // from memory when known
      if (!c.ok()) return c.status();
      ++done;
      if (library.size() != size_before) {
        ++simulated;
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        char stage[200];
        std::snprintf(stage, sizeof stage, "library simulation %d (w = %g, %s, %.1f s)", simulated, *w,
                      cal::geometry_name(key.geometry), s);
        progress(0.9 * done / total, stage);
        if (Status saved = library.save(library_dir); !saved.ok()) {
          notes.push_back("library not saved: " + saved.message());
        }
      }
      if (!plan.mooney_rivlin_w && (*c)->max_deformation() < needed[text] * (1.0 - 1e-12)) {
        // Curves of smaller w end earlier still (strain hardening weakens as w falls): the fit
        // searches w only above this one; their simulations would be wasted.
        cut_w = std::max(cut_w, *w);
        break;
      }
    }
  }
  // A library whose grid stops at cut_w.
  std::unique_ptr<cal::CurveLibrary> narrowed;
  cal::CurveLibrary* fit_library = &library;
  if (cut_w >= 0.0) {
    cal::LibraryOptions narrow = lo;
    narrow.w_grid.clear();
    for (double w : lo.w_grid) {
      if (w >= cut_w) narrow.w_grid.push_back(w);
    }
    if (narrow.w_grid.size() >= 3) {
      // The same curves (from the directory, the server or simulated here), a shorter grid.
      narrowed = std::make_unique<cal::CurveLibrary>(narrow);
      bool copied = true;
      for (const auto& [text, curve] : library.curves())
        copied = copied && narrowed->insert(text, curve).ok();
      if (copied) fit_library = narrowed.get();
    }
  }
  progress(0.9, "fitting " + std::to_string(plan.curves.size()) + " curves");
  StatusOr<cal::FitResult> r = cal::fit_curves(measured_curves(plan), options, *fit_library);
  if (!r.ok()) {
    // The calibration names curve fields relative to the fit ("curves[0].force_n[3]").
    const std::string& m = r.status().message();
    return Status(r.status().code(), m.rfind("curves", 0) == 0 ? "fit." + m : m);
  }
  out.result = std::move(*r);
  out.simulations_run =
      library.simulations_run() + (narrowed ? narrowed->simulations_run() : 0) + out.child_simulations;
  for (std::string& n : notes) out.result.notes.push_back(std::move(n));
  return out;
}

json parameter_fit_json(const FitPlan& plan, const cal::ParameterFit& f,
                        const std::vector<const FitCurvePlan*>& curves) {
  json j;
  j["youngs_modulus_pa"] = estimate_json(f.youngs_modulus_pa);
  j["mooney_rivlin_w"] = estimate_json(f.mooney_rivlin_w);
  j["points"] = f.points;
  j["parameters"] = f.parameters;
  j["objective"] = f.objective;
  j["rms_relative_residual"] = f.rms_relative_residual;
  j["hertz_youngs_modulus_pa"] =
      f.hertz_youngs_modulus_pa ? number(*f.hertz_youngs_modulus_pa) : json(nullptr);
  j["hertz_points"] = f.hertz_points;
  j["hertz_max_deformation"] = plan.hertz_max_deformation;
  json parts = json::array();
  for (std::size_t i = 0; i < f.curves.size(); ++i) {
    const cal::CurvePart& p = f.curves[i];
    // contact_point_m in the coordinates of the sent positions (indentation_m or tip_position_m)
    parts.push_back({{"name", p.name},
                     {"contact_point_m", estimate_json(p.contact_offset_m, curves[i]->contact_estimate_m)},
                     {"rms_relative_residual", p.rms_relative_residual},
                     {"points", p.points.size()}});
  }
  j["curves"] = parts;
  if (f.curves.size() == 1) j["contact_point_m"] = parts[0]["contact_point_m"];
  return j;
}

json fit_document(const FitPlan& plan, const JobFit& fit) {
  json doc;
  doc["geometry"] = fit_geometry_name(plan.geometry);
  doc["model"] = fit_model_name(plan.model);
  doc["w_free"] = !plan.mooney_rivlin_w.has_value();
  doc["poisson_ratio"] = plan.poisson_ratio;
  doc["fit_range_deformation"] = {plan.min_deformation, plan.max_deformation};
  doc["library"] = {{"directory", fit.library_dir},
                    {"target_vertex_count", plan.target_vertex_count},
                    {"load_points", plan.load_points},
                    {"max_deformation", plan.library_max_deformation},
                    {"curves_loaded", fit.curves_loaded},
                    {"server_curves", fit.server_curves},
                    {"child_simulations", fit.child_simulations}};
  doc["simulations_run"] = fit.simulations_run;
  json per = json::array();
  for (std::size_t c = 0; c < fit.result.per_curve.size(); ++c) {
    json j = parameter_fit_json(plan, fit.result.per_curve[c], {&plan.curves[c]});
    j["name"] = plan.curves[c].name;
    j["radius_m"] = plan.curves[c].radius_m;
    j["simulations_run"] = fit.simulations_run;  // the library is shared: the job's count
    per.push_back(std::move(j));
  }
  doc["curves"] = per;
  if (fit.result.joint) {
    std::vector<const FitCurvePlan*> all;
    for (const FitCurvePlan& c : plan.curves) all.push_back(&c);
    doc["joint"] = parameter_fit_json(plan, *fit.result.joint, all);
    doc["joint"]["simulations_run"] = fit.simulations_run;
  } else {
    doc["joint"] = nullptr;
  }
  doc["notes"] = fit.result.notes;
  return doc;
}

std::string fit_stage(const char* what, const cal::ParameterFit& f) {
  std::string s = std::string(what) + ": E " + interval_text(f.youngs_modulus_pa, 1.0, " Pa") + ", w " +
                  interval_text(f.mooney_rivlin_w, 1.0, "");
  if (f.curves.size() == 1) s += ", contact " + interval_text(f.curves[0].contact_offset_m, 1e6, " um");
  char tail[80];
  std::snprintf(tail, sizeof tail, ", rms residual %.3g", f.rms_relative_residual);
  return s + tail;
}

std::string csv_rows(const FitPlan& plan, const JobFit& fit) {
  std::string out;
  auto row = [&](const char* kind, const cal::ParameterFit& f, std::size_t part, const FitCurvePlan& c) {
    const cal::Estimate& s = f.curves[part].contact_offset_m;
    out += std::string(kind) + "," + c.name;
    for (double v :
         {f.youngs_modulus_pa.value, f.youngs_modulus_pa.lower, f.youngs_modulus_pa.upper,
          f.mooney_rivlin_w.value, f.mooney_rivlin_w.lower, f.mooney_rivlin_w.upper,
          s.value + c.contact_estimate_m, s.lower + c.contact_estimate_m, s.upper + c.contact_estimate_m,
          f.curves[part].rms_relative_residual, f.rms_relative_residual}) {
      out += ',';
      if (std::isfinite(v)) out += csv_number(v);
    }
    out += "," + std::to_string(f.curves[part].points.size()) + "," +
           (f.hertz_youngs_modulus_pa ? csv_number(*f.hertz_youngs_modulus_pa) : std::string()) + "," +
           std::to_string(fit.simulations_run) + "\n";
  };
  for (std::size_t c = 0; c < fit.result.per_curve.size(); ++c)
    row("per_curve", fit.result.per_curve[c], 0, plan.curves[c]);
  if (fit.result.joint) {
    for (std::size_t c = 0; c < plan.curves.size(); ++c) row("joint", *fit.result.joint, c, plan.curves[c]);
  }
  return out;
}

class FitRecorder : public ResultRecorder {
 public:
  explicit FitRecorder(io::H5mdWriter* writer) : ResultRecorder(writer) {}

  Status write(const FitPlan& plan, const JobFit& fit) {
    const json doc = fit_document(plan, fit);
    keep(writer_->write_string("/summary/fit_json", doc.dump(2)));
    keep(writer_->write_integer("/summary/simulations_run", fit.simulations_run));
    keep(writer_->write_integer("/summary/curves", static_cast<std::int64_t>(plan.curves.size())));
    const cal::ParameterFit* best = fit.result.joint
                                        ? &*fit.result.joint
                                        : (fit.result.per_curve.empty() ? nullptr : &fit.result.per_curve[0]);
    if (best != nullptr) {
      keep(writer_->write_scalar("/summary/youngs_modulus_pa", best->youngs_modulus_pa.value, "Pa"));
      keep(writer_->write_scalar("/summary/mooney_rivlin_w", best->mooney_rivlin_w.value));
    }
    for (std::size_t c = 0; c < plan.curves.size(); ++c) {
      const FitCurvePlan& curve = plan.curves[c];
      // The curve's own fit when there is one, else the joint fit's part.
      const cal::ParameterFit& f =
          c < fit.result.per_curve.size() ? fit.result.per_curve[c] : *fit.result.joint;
      const cal::CurvePart& part = c < fit.result.per_curve.size() ? f.curves[0] : f.curves[c];
      const double hertz_e = f.hertz_youngs_modulus_pa.value_or(kNaN);
      const std::string prefix = "curve_" + std::to_string(c) + "_";
      // part.points index the plan's arrays (the samples in range), mapped to the spec's sample index.
      for (std::size_t k = 0; k < part.points.size(); ++k) {
        const std::size_t i = part.points[k];
        const std::int64_t step = curve.sample[i];
        const double eps = part.deformation[k];
        const double d = eps * 2.0 * curve.radius_m;
        // Units in the H5MD units syntax; the deformation is dimensionless.
        auto put = [&](const std::string& name, double value, const char* unit) {
          keep(writer_->append_observable(prefix + name, step, eps, value, unit));
        };
        put("indentation_m", curve.indentation_m[i] + curve.contact_estimate_m, "m");
        put("deformation", eps, "");
        put("force_n", curve.force_n[i], "N");
        put("model_force_n", part.model_force_n[k], "N");
        put("hertz_force_n", std::isfinite(hertz_e) ? hertz_force(plan, curve, hertz_e, d) : kNaN, "N");
        if (fit.result.joint && c < fit.result.per_curve.size()) {
          const cal::CurvePart& j = fit.result.joint->curves[c];
          put("joint_model_force_n", k < j.points.size() && j.points[k] == i ? j.model_force_n[k] : kNaN,
              "N");
        }
      }
      keep(writer_->write_string("/summary/curve_" + std::to_string(c) + "_name", curve.name));
    }
    keep(writer_->close());
    return status_;
  }
};

class FitJob final : public PreparedJob {
 public:
  explicit FitJob(FitPlan plan) : plan_(std::move(plan)) {}

  std::string_view scene() const override { return "fit"; }

  // The process baseline, one library simulation (mesh and solver per
  // vertex) and the curves (a few copies of 2 doubles per sample).
  std::int64_t memory_bytes() const override {
    const std::int64_t sim =
        plan_.model == FitModelKind::kHertz ? 0 : plan_.target_vertex_count * kBytesPerVertex;
    return kBaselineBytes + sim + plan_.total_samples * 128;
  }

  RunOutcome run(const v1::JobSpec& spec, const RunOptions& options, const JobEvents& events) override {
    RunOutcome outcome;
    io::H5mdCreator creator;
    // No physical time: "time" is the fitted deformation of the sample, dimensionless.
    creator.time_unit = "";
    creator.time_meaning =
        "not time: the fitted deformation ((indentation - contact offset) / (2 R)) of the sample; "
        "step is the sample's index in the spec's arrays";
    // The server's curves are input of this attempt, not of the job: not in the result's spec.
    v1::JobSpec written_spec = spec;
    written_spec.mutable_fit()->clear_server_library();
    auto writer = open_result(written_spec, options, creator);
    if (!writer.ok()) {
      outcome.status = writer.status();
      return outcome;
    }
    Hooks hooks{events.progress, events.should_stop};
    const std::string dir = options.library_dir.empty() ? default_library_dir() : options.library_dir;
    StatusOr<JobFit> fit =
        compute(plan_, dir, options.threads, hooks, spec.has_fit() ? &spec.fit().server_library() : nullptr);
    if (!fit.ok()) {
      (void)(*writer)->close();
      outcome.status = fit.status();
      outcome.result_written = true;  // the spec only
      return outcome;
    }
    FitRecorder recorder(writer->get());
    const Status written = recorder.write(plan_, *fit);
    if (events.progress) {
      // One last stage (the worker keeps one progress report per fraction and
      // at most five a second): the joint fit, or the one curve's; every
      // curve's fit is in the result file.
      const std::size_t n = plan_.curves.size();
      std::string stage =
          fit->result.joint
              ? fit_stage(("fit joint (" + std::to_string(n) + " curves)").c_str(), *fit->result.joint)
              : fit_stage(("fit " + plan_.curves[0].name).c_str(), fit->result.per_curve[0]);
      if (n > 1 && !fit->result.per_curve.empty()) stage += "; per curve: in the result";
      stage += "; simulations run " + std::to_string(fit->simulations_run);
      events.progress(1.0, stage);
    }
    return outcome_of(Status::ok_status(), written, 0);
  }

  Status run_csv(const CsvSink& sink, int threads) override {
    Hooks hooks;
    if (sink.progress) {
      hooks.progress = [&](double f, const std::string& stage) {
        *sink.progress << static_cast<int>(100 * f) << " %  " << stage << '\n' << std::flush;
      };
    }
    StatusOr<JobFit> fit = compute(plan_, default_library_dir(), threads, hooks);
    sink.csv << fit_csv_header() << '\n' << std::flush;
    if (!fit.ok()) return fit.status();
    sink.csv << csv_rows(plan_, *fit) << std::flush;
    if (sink.progress) {
      for (const std::string& n : fit->result.notes) *sink.progress << "note: " << n << '\n';
    }
    return Status::ok_status();
  }

 private:
  FitPlan plan_;
};

}  // namespace

std::string default_library_dir() {
  if (const char* d = std::getenv("CELLFLOW_LIBRARY_DIR"); d != nullptr && *d != '\0') return d;
  if (const char* d = std::getenv("XDG_CACHE_HOME"); d != nullptr && *d != '\0') {
    return std::string(d) + "/cellflow/curves";
  }
  if (const char* d = std::getenv("HOME"); d != nullptr && *d != '\0')
    return std::string(d) + "/.cache/cellflow/curves";
  const char* tmp = std::getenv("TMPDIR");
  return std::string(tmp != nullptr && *tmp != '\0' ? tmp : "/tmp") + "/cellflow-curves";
}

std::string fit_csv_header() {
  return "fit,curve,youngs_modulus_pa,youngs_modulus_lower_pa,youngs_modulus_upper_pa,mooney_rivlin_w,"
         "mooney_rivlin_w_lower,mooney_rivlin_w_upper,contact_point_m,contact_point_lower_m,contact_point_"
         "upper_m,"
         "curve_rms_relative_residual,fit_rms_relative_residual,points,hertz_youngs_modulus_pa,simulations_"
         "run";
}

StatusOr<std::unique_ptr<PreparedJob>> prepare_fit(const v1::JobSpec& spec) {
  StatusOr<FitPlan> plan = to_fit_plan(spec.fit());
  if (!plan.ok()) return plan.status();
  return std::unique_ptr<PreparedJob>(new FitJob(std::move(*plan)));
}

}  // namespace cellflow::jobs
