#include "bench/accuracy/accuracy_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>
#include <utility>

#include "bench/accuracy/accuracy_metrics.h"

namespace cellflow::bench {

namespace {

std::string error_text(double e) {
  return std::isfinite(e) ? number_text(e, "%.3e") : "n/a";
}

std::string csv_quoted(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

Status write_text(const std::string& path, const std::string& text) {
  std::ofstream file(path);
  if (!file) return Status(StatusCode::kInvalidArgument, "cannot write " + path);
  file << text;
  file.close();
  if (!file) return Status(StatusCode::kInternal, "error writing " + path);
  return Status();
}

std::string xml_escaped(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '<')
      out += "&lt;";
    else if (c == '>')
      out += "&gt;";
    else if (c == '&')
      out += "&amp;";
    else
      out += c;
  }
  return out;
}

}  // namespace

std::string number_text(double x, const char* fmt) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, fmt, x);
  return buffer;
}

Status write_csv(const std::string& path, const std::vector<AccuracyRow>& rows, const ReportLabels& labels) {
  const bool result = !labels.result_csv.empty(), analytic = !labels.analytic_csv.empty();
  std::ostringstream out;
  out << "sweep,value,numeric_value,default,reference,wall_s,cpu_s," << labels.iterations_csv << ','
      << (result ? labels.result_csv + "," : "") << "error,total_error,"
      << (analytic ? labels.analytic_csv + "," : "") << "status\n";
  for (const auto& r : rows) {
    out << r.sweep << ',' << csv_quoted(r.value) << ',' << number_text(r.numeric_value, "%.6g") << ','
        << (r.is_default ? 1 : 0) << ',' << (r.is_reference ? 1 : 0) << ',' << number_text(r.wall_s, "%.3f")
        << ',' << number_text(r.cpu_s, "%.3f") << ',' << r.iterations << ',';
    if (result) out << number_text(r.result, "%.6e") << ',';
    out << number_text(r.error, "%.6e") << ',' << number_text(r.total_error, "%.6e") << ',';
    if (analytic) out << number_text(r.analytic_error, "%.6e") << ',';
    out << csv_quoted(r.status) << '\n';
  }
  return write_text(path, out.str());
}

Status write_markdown(const std::string& path, const std::string& heading,
                      const std::vector<AccuracyRow>& rows, const ReportLabels& labels) {
  const bool result = !labels.result_md.empty(), analytic = !labels.analytic_md.empty();
  std::ostringstream out;
  out << heading << "\n\n";
  out << "| setting | value | wall time [s] | " << (labels.cpu_time_axis ? "CPU time [s] | " : "")
      << (result ? labels.result_md + " | " : "") << "error | total error | "
      << (analytic ? labels.analytic_md + " | " : "") << labels.iterations_md << " | status |\n";
  out << "|---|---|---|" << (labels.cpu_time_axis ? "---|" : "") << (result ? "---|" : "") << "---|---|"
      << (analytic ? "---|" : "") << "---|---|\n";
  for (const auto& r : rows) {
    std::string value = r.value;
    if (r.is_default) value += " **(default)**";
    if (r.is_reference) value += " (reference)";
    out << "| " << r.sweep << " | " << value << " | " << number_text(r.wall_s, "%.2f") << " | ";
    if (labels.cpu_time_axis) out << number_text(r.cpu_s, "%.2f") << " | ";
    if (result) out << (std::isfinite(r.result) ? number_text(r.result, "%.5g") : "n/a") << " | ";
    out << (r.is_reference && r.error == 0.0 ? "0 (reference)" : error_text(r.error)) << " | "
        << error_text(r.total_error) << " | ";
    if (analytic) out << error_text(r.analytic_error) << " | ";
    out << r.iterations << " | " << r.status << " |\n";
  }
  return write_text(path, out.str());
}

Status write_svg(const std::string& path, const std::string& title, const std::vector<AccuracyRow>& rows,
                 const ReportLabels& labels) {
  // one point per run
  std::vector<const AccuracyRow*> points;
  std::set<std::string> seen;
  for (const auto& r : rows) {
    const double t = labels.cpu_time_axis ? r.cpu_s : r.wall_s;
    if (!(std::isfinite(r.total_error) && r.total_error > 0.0 && t > 0.0)) continue;
    if (!seen.insert(r.run_key).second) continue;
    points.push_back(&r);
  }
  std::vector<double> times, errors;
  for (const auto* p : points) {
    times.push_back(labels.cpu_time_axis ? p->cpu_s : p->wall_s);
    errors.push_back(p->total_error);
  }
  const std::vector<bool> front = pareto_front(times, errors);

  constexpr double kWidth = 760, kHeight = 520, kLeft = 90, kRight = 200, kTop = 50, kBottom = 70;
  const double plot_w = kWidth - kLeft - kRight, plot_h = kHeight - kTop - kBottom;
  // decades spanning the data
  double t_lo = 1.0, t_hi = 10.0, e_lo = 1e-3, e_hi = 1e-1;
  if (!points.empty()) {
    t_lo = std::floor(std::log10(*std::min_element(times.begin(), times.end())));
    t_hi = std::ceil(std::log10(*std::max_element(times.begin(), times.end())));
    e_lo = std::floor(std::log10(*std::min_element(errors.begin(), errors.end())));
    e_hi = std::ceil(std::log10(*std::max_element(errors.begin(), errors.end())));
    if (t_hi <= t_lo) t_hi = t_lo + 1;
    if (e_hi <= e_lo) e_hi = e_lo + 1;
  } else {
    t_lo = 0, t_hi = 1, e_lo = -3, e_hi = -1;
  }
  const auto x_of = [&](double t) { return kLeft + (std::log10(t) - t_lo) / (t_hi - t_lo) * plot_w; };
  const auto y_of = [&](double e) { return kTop + (e_hi - std::log10(e)) / (e_hi - e_lo) * plot_h; };

  // one colour per sweep, in the order the sweeps first appear
  static constexpr const char* kPalette[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728",
                                             "#9467bd", "#8c564b", "#e377c2"};
  std::vector<std::pair<std::string, std::string>> colours;
  for (const auto& r : rows) {
    const bool known =
        std::any_of(colours.begin(), colours.end(), [&](const auto& c) { return c.first == r.sweep; });
    if (!known) colours.emplace_back(r.sweep, kPalette[colours.size() % std::size(kPalette)]);
  }
  const auto colour_of = [&](const std::string& sweep) {
    for (const auto& [name, colour] : colours)
      if (name == sweep) return colour;
    return std::string("#7f7f7f");
  };

  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << kWidth << "\" height=\"" << kHeight
    << "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  s << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  s << "<text x=\"" << kWidth / 2 << "\" y=\"24\" text-anchor=\"middle\" font-size=\"14\">"
    << xml_escaped(title) << "</text>\n";
  s << "<rect x=\"" << kLeft << "\" y=\"" << kTop << "\" width=\"" << plot_w << "\" height=\"" << plot_h
    << "\" fill=\"none\" stroke=\"black\"/>\n";
  for (int d = static_cast<int>(t_lo); d <= static_cast<int>(t_hi); ++d) {
    const double x = x_of(std::pow(10.0, d));
    s << "<line x1=\"" << x << "\" y1=\"" << kTop << "\" x2=\"" << x << "\" y2=\"" << kTop + plot_h
      << "\" stroke=\"#ddd\"/>\n";
    s << "<text x=\"" << x << "\" y=\"" << kTop + plot_h + 18 << "\" text-anchor=\"middle\">1e" << d
      << "</text>\n";
  }
  for (int d = static_cast<int>(e_lo); d <= static_cast<int>(e_hi); ++d) {
    const double y = y_of(std::pow(10.0, d));
    s << "<line x1=\"" << kLeft << "\" y1=\"" << y << "\" x2=\"" << kLeft + plot_w << "\" y2=\"" << y
      << "\" stroke=\"#ddd\"/>\n";
    s << "<text x=\"" << kLeft - 8 << "\" y=\"" << y + 4 << "\" text-anchor=\"end\">1e" << d << "</text>\n";
  }
  s << "<text x=\"" << kLeft + plot_w / 2 << "\" y=\"" << kHeight - 25 << "\" text-anchor=\"middle\">"
    << (labels.cpu_time_axis ? "CPU time [s]" : "wall time [s]") << "</text>\n";
  s << "<text x=\"20\" y=\"" << kTop + plot_h / 2 << "\" text-anchor=\"middle\" transform=\"rotate(-90 20 "
    << kTop + plot_h / 2 << ")\">" << xml_escaped(labels.error_axis) << "</text>\n";

  // Pareto front: its points in order of time
  std::vector<std::size_t> on_front;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (front[i]) on_front.push_back(i);
  std::sort(on_front.begin(), on_front.end(), [&](auto a, auto b) { return times[a] < times[b]; });
  if (!on_front.empty()) {
    s << "<polyline fill=\"none\" stroke=\"black\" stroke-dasharray=\"5,3\" points=\"";
    for (auto i : on_front) s << x_of(times[i]) << ',' << y_of(errors[i]) << ' ';
    s << "\"/>\n";
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double x = x_of(times[i]), y = y_of(errors[i]);
    s << "<circle cx=\"" << x << "\" cy=\"" << y << "\" r=\"4\" fill=\"" << colour_of(points[i]->sweep)
      << "\"><title>" << xml_escaped(points[i]->sweep + " " + points[i]->value) << "</title></circle>\n";
    if (front[i])
      s << "<rect x=\"" << x - 7 << "\" y=\"" << y - 7 << "\" width=\"14\" height=\"14\" fill=\"none\" "
        << "stroke=\"black\"/>\n";
    if (points[i]->is_default)
      s << "<circle cx=\"" << x << "\" cy=\"" << y << "\" r=\"10\" fill=\"none\" stroke=\"purple\" "
        << "stroke-width=\"2\"/>\n";
    std::string label = points[i]->is_default ? "default" : points[i]->value;
    s << "<text x=\"" << x + 8 << "\" y=\"" << y - 6 << "\" font-size=\"10\">" << xml_escaped(label)
      << "</text>\n";
  }
  // legend
  double ly = kTop + 10;
  const double lx = kLeft + plot_w + 20;
  for (const auto& [sweep, colour] : colours) {
    s << "<circle cx=\"" << lx << "\" cy=\"" << ly << "\" r=\"4\" fill=\"" << colour << "\"/>";
    s << "<text x=\"" << lx + 10 << "\" y=\"" << ly + 4 << "\">" << sweep << "</text>\n";
    ly += 18;
  }
  s << "<rect x=\"" << lx - 7 << "\" y=\"" << ly - 7 << "\" width=\"14\" height=\"14\" fill=\"none\" "
    << "stroke=\"black\"/><text x=\"" << lx + 10 << "\" y=\"" << ly + 4 << "\">Pareto front</text>\n";
  ly += 20;
  s << "<circle cx=\"" << lx << "\" cy=\"" << ly << "\" r=\"8\" fill=\"none\" stroke=\"purple\" "
    << "stroke-width=\"2\"/><text x=\"" << lx + 12 << "\" y=\"" << ly + 4 << "\">default</text>\n";
  s << "</svg>\n";
  return write_text(path, s.str());
}

}  // namespace cellflow::bench
