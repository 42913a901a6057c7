#include "client/fit_output.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <tuple>

#include "client/svg_plot.h"
#include "io/h5md.h"

namespace cellflow::client {
namespace {

using json = nlohmann::json;

std::string csv_value(double v) {
  if (!std::isfinite(v)) return "";
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.17g", v);
  return buffer;
}

// Shifts an estimate {value, lower, upper} by `by` (nulls stay null).
void shift(json& estimate, double by) {
  for (const char* k : {"value", "lower", "upper"}) {
    if (estimate.contains(k) && estimate[k].is_number()) estimate[k] = estimate[k].get<double>() + by;
  }
}

StatusOr<json> report_document(const std::string& fit_json, const FitReport& report) {
  json doc = json::parse(fit_json, nullptr, false);
  if (doc.is_discarded() || !doc.is_object()) return invalid_argument("the result's fit JSON does not parse");
  json out;
  out["job"] = report.job_id;
  out["geometry"] = doc["geometry"];
  out["model"] = doc["model"];
  out["w_free"] = doc["w_free"];
  out["poisson_ratio"] = doc["poisson_ratio"];
  out["fit_range_deformation"] = doc["fit_range_deformation"];
  out["library"] = doc["library"];
  out["simulations_run"] = doc["simulations_run"];
  auto at = [&](std::size_t i) {
    return i < report.contact_estimates_m.size() ? report.contact_estimates_m[i] : 0.0;
  };
  auto file = [&](std::size_t i, const json& part) {
    return i < report.files.size() ? json(report.files[i]) : part.value("name", json(""));
  };
  auto entry = [&](const json& f) {
    json e;
    for (const char* k : {"youngs_modulus_pa", "mooney_rivlin_w"}) e[k] = f[k];
    e["rms_relative_residual"] = f["rms_relative_residual"];
    e["objective"] = f["objective"];
    e["points"] = f["points"];
    e["hertz_youngs_modulus_pa"] = f["hertz_youngs_modulus_pa"];
    e["hertz_max_deformation"] = f["hertz_max_deformation"];
    e["hertz_points"] = f["hertz_points"];
    e["simulations_run"] = f["simulations_run"];
    return e;
  };
  json curves = json::array();
  for (std::size_t i = 0; doc["curves"].is_array() && i < doc["curves"].size(); ++i) {
    const json& f = doc["curves"][i];
    json e = entry(f);
    e["file"] = file(i, f);
    e["contact_point_m"] = f["contact_point_m"];
    shift(e["contact_point_m"], at(i));
    curves.push_back(std::move(e));
  }
  out["curves"] = curves;
  if (doc["joint"].is_object()) {
    json j = entry(doc["joint"]);
    json parts = json::array();
    for (std::size_t i = 0; i < doc["joint"]["curves"].size(); ++i) {
      json p;
      p["file"] = file(i, doc["joint"]["curves"][i]);
      p["contact_point_m"] = doc["joint"]["curves"][i]["contact_point_m"];
      shift(p["contact_point_m"], at(i));
      p["rms_relative_residual"] = doc["joint"]["curves"][i]["rms_relative_residual"];
      parts.push_back(std::move(p));
    }
    j["curves"] = parts;
    out["joint"] = std::move(j);
  } else {
    out["joint"] = nullptr;
  }
  out["notes"] = doc["notes"];
  return out;
}

std::string estimate_text(const json& e, double scale, int digits) {
  if (!e.is_object() || !e["value"].is_number()) return "-";
  char buffer[120];
  const double v = e["value"].get<double>() * scale;
  if (e.value("fixed", false)) {
    std::snprintf(buffer, sizeof buffer, "%.*g (fixed)", digits, v);
  } else if (e["lower"].is_number() && e["upper"].is_number()) {
    std::snprintf(buffer, sizeof buffer, "%.*g [%.*g, %.*g]%s", digits, v, digits,
                  e["lower"].get<double>() * scale, digits, e["upper"].get<double>() * scale,
                  e.value("lower_at_bound", false) || e.value("upper_at_bound", false) ? "*" : "");
  } else {
    std::snprintf(buffer, sizeof buffer, "%.*g", digits, v);
  }
  return buffer;
}

std::string number_or_dash(const json& v, const char* format) {
  if (!v.is_number()) return "-";
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, format, v.get<double>());
  return buffer;
}

}  // namespace

bool is_fit_result(const std::string& h5_path) {
  return io::read_string(h5_path, "/summary/fit_json").ok();
}

StatusOr<std::string> read_fit_json(const std::string& h5_path) {
  return io::read_string(h5_path, "/summary/fit_json");
}

StatusOr<std::vector<FitCurveSeries>> read_fit_curves(const std::string& h5_path) {
  StatusOr<double> count = io::read_scalar(h5_path, "/summary/curves");
  if (!count.ok()) return count.status();
  std::vector<FitCurveSeries> out;
  for (int c = 0; c < static_cast<int>(*count); ++c) {
    FitCurveSeries s;
    const std::string prefix = "curve_" + std::to_string(c) + "_";
    if (auto name = io::read_string(h5_path, "/summary/" + prefix + "name"); name.ok()) s.name = *name;
    auto read = [&](const char* what, std::vector<double>& into, bool required) -> Status {
      StatusOr<io::TimeSeries> t = io::read_observable(h5_path, prefix + what);
      if (!t.ok()) return required ? t.status() : Status::ok_status();
      into = t->value;
      if (s.sample.empty()) s.sample.assign(t->step.begin(), t->step.end());
      return Status::ok_status();
    };
    for (auto [what, into, required] :
         {std::tuple{"indentation_m", &s.indentation_m, true},
          std::tuple{"deformation", &s.deformation, true}, std::tuple{"force_n", &s.force_n, true},
          std::tuple{"model_force_n", &s.model_force_n, true},
          std::tuple{"hertz_force_n", &s.hertz_force_n, true},
          std::tuple{"joint_model_force_n", &s.joint_model_force_n, false}}) {
      if (Status st = read(what, *into, required); !st.ok()) return st;
    }
    out.push_back(std::move(s));
  }
  return out;
}

std::string fit_curves_csv(const std::vector<FitCurveSeries>& curves) {
  std::string out =
      "curve,name,sample,indentation_m,deformation,force_n,model_force_n,hertz_force_n,joint_model_force_n\n";
  for (std::size_t c = 0; c < curves.size(); ++c) {
    const FitCurveSeries& s = curves[c];
    for (std::size_t i = 0; i < s.deformation.size(); ++i) {
      out += std::to_string(c) + "," + s.name + "," + std::to_string(s.sample[i]) + "," +
             csv_value(s.indentation_m[i]) + "," + csv_value(s.deformation[i]) + "," +
             csv_value(s.force_n[i]) + "," + csv_value(s.model_force_n[i]) + "," +
             csv_value(s.hertz_force_n[i]) + "," +
             (i < s.joint_model_force_n.size() ? csv_value(s.joint_model_force_n[i]) : std::string()) + "\n";
    }
  }
  return out;
}

std::string fit_svg(const std::vector<FitCurveSeries>& curves, const std::string& title) {
  double x_lo = 0.0, x_hi = 0.0, f_min = 0.0, f_max = 0.0;
  for (const auto& s : curves) {
    for (std::size_t i = 0; i < s.deformation.size(); ++i) {
      x_lo = std::min(x_lo, s.deformation[i]);
      x_hi = std::max(x_hi, s.deformation[i]);
      for (double f : {s.force_n[i], s.model_force_n[i]}) {
        if (std::isfinite(f)) f_min = std::min(f_min, f), f_max = std::max(f_max, f);
      }
    }
  }
  const ForceUnit unit = force_unit(f_max);  // the largest force in [1, 1000) of the unit
  const PlotAxis xa = nice_axis(x_lo, x_hi > x_lo ? x_hi : x_lo + 1.0);
  const PlotAxis ya =
      nice_axis(f_min / unit.scale, f_max > f_min ? f_max / unit.scale : f_min / unit.scale + 1.0);
  const char* colors[] = {"#1f77b4", "#2ca02c", "#9467bd", "#8c564b",
                          "#e377c2", "#17becf", "#bcbd22", "#7f7f7f"};
  // The legend first: the frame makes room for it right of the plotting area.
  std::vector<PlotSeries> legend;
  PlotSeries hertz;
  hertz.color = "#d62728";
  hertz.dash = "7,5";
  hertz.label = "Hertz";
  for (std::size_t c = 0; c < curves.size(); ++c) {
    PlotSeries model;
    model.color = colors[c % 8];
    model.label = curves[c].name + ": data, model";
    model.markers = true;
    legend.push_back(model);
  }
  if (!curves.empty()) legend.push_back(hertz);
  const PlotFrame frame = frame_with_legend(legend);
  auto px = [&](double x) { return frame.x_of(xa, x); };
  auto py = [&](double f) { return frame.y_of(ya, f / unit.scale); };
  std::string svg = svg_open(frame, title);
  svg += svg_axes(
      frame, xa.ticks, ya.ticks, px, [&](double t) { return py(t * unit.scale); }, "deformation \u03b4 / 2R",
      "force (" + std::string(unit.name) + ")");
  for (std::size_t c = 0; c < curves.size(); ++c) {
    const FitCurveSeries& s = curves[c];
    const std::string color = colors[c % 8];
    auto polyline = [&](const std::vector<double>& f, const PlotSeries& style) {
      std::string points;
      for (std::size_t i = 0; i < s.deformation.size() && i < f.size(); ++i) {
        if (std::isfinite(f[i])) points += fixed(px(s.deformation[i]), 2) + "," + fixed(py(f[i]), 2) + " ";
      }
      return "<polyline fill=\"none\" " + svg_stroke(style) + " points=\"" + points + "\"/>\n";
    };
    for (std::size_t i = 0; i < s.deformation.size(); ++i) {
      svg += "<circle cx=\"" + fixed(px(s.deformation[i]), 2) + "\" cy=\"" + fixed(py(s.force_n[i]), 2) +
             "\" r=\"2\" fill=\"none\" stroke=\"" + color + "\"/>\n";
    }
    svg += polyline(s.hertz_force_n, hertz);
    svg += polyline(s.model_force_n, legend[c]);
  }
  svg += svg_legend(frame, legend);
  svg += "</svg>\n";
  return svg;
}

StatusOr<std::string> fit_json_report(const std::string& fit_json, const FitReport& report) {
  StatusOr<json> doc = report_document(fit_json, report);
  if (!doc.ok()) return doc.status();
  return doc->dump(2);
}

StatusOr<std::string> fit_table(const std::string& fit_json, const FitReport& report) {
  StatusOr<json> doc = report_document(fit_json, report);
  if (!doc.ok()) return doc.status();
  const json& d = *doc;
  std::string out;
  char line[512];
  std::snprintf(line, sizeof line, "%-32s %-28s %-24s %-28s %-9s %s\n", "curve", "E (Pa) [95 %]", "w [95 %]",
                "contact (um) [95 %]", "rms res", "Hertz E (Pa)");
  out += line;
  auto row = [&](const std::string& name, const json& f, const json& contact) {
    std::snprintf(line, sizeof line, "%-32s %-28s %-24s %-28s %-9s %s\n", name.c_str(),
                  estimate_text(f["youngs_modulus_pa"], 1.0, 4).c_str(),
                  estimate_text(f["mooney_rivlin_w"], 1.0, 3).c_str(), estimate_text(contact, 1e6, 4).c_str(),
                  number_or_dash(f["rms_relative_residual"], "%.3g").c_str(),
                  number_or_dash(f["hertz_youngs_modulus_pa"], "%.4g").c_str());
    out += line;
  };
  for (const json& c : d["curves"]) row(c["file"].get<std::string>(), c, c["contact_point_m"]);
  if (d["joint"].is_object()) {
    row("joint (" + std::to_string(d["joint"]["curves"].size()) + " curves)", d["joint"], json());
    for (const json& p : d["joint"]["curves"]) {
      std::snprintf(line, sizeof line, "  %-30s contact %s um\n", p["file"].get<std::string>().c_str(),
                    estimate_text(p["contact_point_m"], 1e6, 4).c_str());
      out += line;
    }
  }
  std::snprintf(line, sizeof line, "simulations run: %d (library %s)\n", d["simulations_run"].get<int>(),
                d["library"]["directory"].get<std::string>().c_str());
  out += line;
  for (const json& n : d["notes"]) out += "note: " + n.get<std::string>() + "\n";
  out += "(* an interval reached the parameter's range)\n";
  return out;
}

}  // namespace cellflow::client
