// cellflow: the command-line client of the cellflow job service.
#include <google/protobuf/util/json_util.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <sstream>

#include "client/curve_output.h"
#include "client/exit_codes.h"
#include "client/fit_input.h"
#include "client/fit_output.h"
#include "client/flow_output.h"
#include "client/output_file.h"
#include "client/rpc_client.h"
#include "client/spec_arg.h"
#include "client/study_output.h"
#include "client/suggest.h"
#include "client/suspension_output.h"
#include "client/version.h"
#include "client/watch_printer.h"
#include "io/xdmf.h"
#include "jobs/spec_json.h"

namespace {

using namespace cellflow;
using client::ExitCode;
namespace fs = std::filesystem;

int report_error(const grpc::Status& status, const std::string& what) {
  std::fprintf(stderr, "cellflow: %s: %s (%s)\n", what.c_str(), status.error_message().c_str(),
               status.error_code() == grpc::StatusCode::UNAVAILABLE ? "server unreachable" : "refused");
  return client::exit_code_for(status);
}

std::string to_json(const google::protobuf::Message& message) {
  std::string json;
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = true;
  options.preserve_proto_field_names = true;
  (void)google::protobuf::util::MessageToJsonString(message, &json, options);
  return json;
}

std::string random_request_id() {
  std::random_device device;
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "cli-%08x%08x%08x", device(), device(), device());
  return buffer;
}

std::string time_string(const google::protobuf::Timestamp& t) {
  if (t.seconds() == 0) return "-";
  const std::time_t seconds = t.seconds();
  char buffer[32];
  std::strftime(buffer, sizeof buffer, "%Y-%m-%d %H:%M:%S", std::localtime(&seconds));
  return buffer;
}

std::string scene_of(const v1::JobSpec& spec) {
  const std::string_view name = jobs::scene_name(spec);
  return name.empty() ? "-" : std::string(name);
}

void print_job(const v1::Job& job) {
  std::printf("%s  %s  %s  attempt %d  %.0f%%", job.id().c_str(), v1::Job::State_Name(job.state()).c_str(),
              scene_of(job.spec()).c_str(), job.attempt(), 100.0 * job.fraction_done());
  if (job.child_count() > 0)
    std::printf("  study: %d/%d children done", job.children_done(), job.child_count());
  if (!job.parent_job_id().empty())
    std::printf("  child %d of %s", job.child_index(), job.parent_job_id().c_str());
  if (!job.spec().name().empty()) std::printf("  \"%s\"", job.spec().name().c_str());
  if (!job.reason().empty()) std::printf("  reason: %s", job.reason().c_str());
  std::printf("\n");
}

// Cell and material flags shared by both scenes.
struct CellFlags {
  double radius_m = 0, youngs_modulus_pa = 0, poisson_ratio = 0, w = 0;
  int target_vertex_count = 0;
  std::string mesh_file;

  void add(CLI::App* app) {
    app->add_option("--radius-m", radius_m, "cell radius R in metres")->required();
    app->add_option("--youngs-modulus-pa", youngs_modulus_pa, "Young's modulus E in pascals")->required();
    app->add_option("--poisson-ratio", poisson_ratio, "Poisson ratio nu in (-1, 0.5) (server default 0.48)");
    app->add_option("--w", w, "Mooney-Rivlin weight w in [0, 1]; 1 = neo-Hookean (server default 1)");
    app->add_option("--target-vertex-count", target_vertex_count,
                    "mesh size, 200..20000 (server default 3000)");
    app->add_option(
        "--mesh-file", mesh_file,
        "Gmsh .msh v4 ASCII mesh instead of a generated sphere (uploaded; the spec names its hash)");
  }
  void fill(CLI::App* app, v1::CellSpec* cell) const {
    cell->set_radius_m(radius_m);
    cell->mutable_material()->set_youngs_modulus_pa(youngs_modulus_pa);
    if (app->count("--poisson-ratio")) cell->mutable_material()->set_poisson_ratio(poisson_ratio);
    if (app->count("--w")) cell->mutable_material()->set_mooney_rivlin_w(w);
    if (app->count("--target-vertex-count")) cell->set_target_vertex_count(target_vertex_count);
    if (!mesh_file.empty()) cell->set_mesh_file(mesh_file);
  }
};

int watch(client::Client& client, const std::string& job_id, std::int64_t after, bool quiet) {
  const bool terminal = ::isatty(STDOUT_FILENO) != 0;
  client::WatchPrinter printer(stdout, terminal);
  // A study: the bar counts its children (ChildUpdate events).
  if (v1::Job job; client.get(job_id, &job).ok() && job.child_count() > 0)
    printer.set_child_count(job.child_count());
  const grpc::Status status = client.watch(job_id, after, [&](const v1::JobEvent& event) {
    if (!quiet || event.has_state_change()) printer.print(event);
    return true;
  });
  printer.finish();
  if (!status.ok()) return report_error(status, "watch " + job_id);
  return client::exit_code_for(printer.last_state());
}

// The server reads no file a spec names: a cell's mesh_file (from --mesh-file
// or a JSON spec) is read here, uploaded, and replaced by its hash.
int upload_mesh_file(client::Client& client, v1::JobSpec& spec) {
  for (const jobs::SceneCell& scene_cell : jobs::scene_cells(spec)) {  // every cell of whichever scene
    v1::CellSpec* cell = scene_cell.cell;
    if (cell->mesh_file().empty()) continue;
    std::ifstream in(cell->mesh_file(), std::ios::binary);
    std::ostringstream bytes;
    bytes << in.rdbuf();
    if (!in && !in.eof()) {
      std::fprintf(stderr, "cellflow: cannot read the mesh file %s\n", cell->mesh_file().c_str());
      return ExitCode::kExitInvalidArgument;
    }
    v1::MeshRef ref;
    const std::string name = std::filesystem::path(cell->mesh_file()).filename().string();
    const grpc::Status status = client.upload_mesh(bytes.str(), name, &ref);
    if (!status.ok()) return report_error(status, "upload mesh " + cell->mesh_file());
    cell->clear_mesh_file();
    cell->set_mesh_sha256(ref.sha256());
  }
  return ExitCode::kExitOk;
}

// Downloads the result of `job_id` to a temporary file (removed on exit).
struct TemporaryResult {
  std::string path;
  ~TemporaryResult() {
    if (!path.empty()) std::remove(path.c_str());
  }
};

// `cellflow fit`: the flags of one fit job.
struct FitFlags {
  std::vector<std::string> files;
  std::string geometry, model = "mooney-rivlin", range, range_unit = "deformation", request_id, name;
  double radius_m = 0, probe_radius_m = 0, tip_radius_m = 0, w = 1, poisson_ratio = 0.48;
  double spring_constant = 0, sensitivity = 0, library_max_deformation = 0, contact_window_radii = 0;
  int vertices = 0, load_points = 0;
  bool w_free = false, watch = false, json = false, no_per_curve = false, no_joint = false,
       print_spec = false, contact_at_zero = false;

  void add(CLI::App* app) {
    app->add_option("files", files,
                    "force-curve files (JPK .jpk-force, AFM Workshop CSV, NT-MDT txt, tab export, "
                    "CSV/TSV with named columns)")
        ->required();
    app->add_option("--geometry", geometry,
                    "plates (flat cantilever / FluidFM), probe (colloidal probe), tip")
        ->required()
        ->check(CLI::IsMember({"plates", "probe", "tip"}));
    app->add_option("--radius-m", radius_m, "cell radius R in metres")->required();
    app->add_option("--probe-radius-m", probe_radius_m, "colloidal probe radius (geometry probe)");
    app->add_option("--tip-radius-m", tip_radius_m, "tip apex radius (geometry tip)");
    app->add_option("--model", model,
                    "mooney-rivlin (default), neo-hookean (w = 1) or hertz (no simulations)")
        ->check(CLI::IsMember({"mooney-rivlin", "neo-hookean", "hertz"}));
    auto* w_option =
        app->add_option("--w", w, "fixed Mooney-Rivlin ratio w in [0, 1] (default 1 unless --w-free)");
    app->add_flag("--w-free", w_free, "fit w in [0, 1]")->excludes(w_option);
    app->add_option("--poisson-ratio", poisson_ratio, "nu in (-1, 0.5) (default 0.48)");
    app->add_option("--range", range, "fit range MIN:MAX (default -0.05:0.7 in deformation x/2R)");
    app->add_option("--range-unit", range_unit, "deformation (x/2R) or m (metres past the contact estimate)")
        ->check(CLI::IsMember({"deformation", "m"}));
    app->add_option("--spring-constant", spring_constant,
                    "cantilever spring constant N/m (overrides the file)");
    app->add_option("--sensitivity", sensitivity, "deflection sensitivity m/V (overrides the file)");
    app->add_option("--vertices", vertices, "library numerics: sphere mesh vertices (server default 3000)");
    app->add_option("--load-points", load_points, "library numerics: points per curve (server default 30)");
    app->add_option("--library-max-deformation", library_max_deformation,
                    "library numerics: last deformation of the curves (default 0.75)");
    app->add_option("--contact-window-radii", contact_window_radii,
                    "contact point searched within +-c R of the estimate (default 0.1)");
    app->add_flag("--contact-at-zero", contact_at_zero,
                  "the curves start at contact (a finite-element reference, processed data): position 0 "
                  "is the contact point and the force has no offset; skip baseline and contact estimation "
                  "(the fit still refines the contact within --contact-window-radii)");
    app->add_flag("--no-per-curve", no_per_curve, "joint fit only");
    app->add_flag("--no-joint", no_joint, "per-curve fits only");
    app->add_option("--request-id", request_id, "idempotency key");
    app->add_option("--name", name, "a name for the job");
    app->add_flag("--watch", watch, "print the job's events while it runs");
    app->add_flag("--json", json, "print the fit as JSON (per curve and joint, 95 % bounds)");
    app->add_flag(
        "--print-spec", print_spec,
        "print the job spec (with the curves as data) as JSON and exit: for cellflow-run or submit --spec");
  }
};

int run_fit(client::Client& client, CLI::App* app, const FitFlags& flags) {
  if (!(flags.radius_m > 0.0)) {
    std::fprintf(stderr, "cellflow: --radius-m = %g must be > 0\n", flags.radius_m);
    return ExitCode::kExitUsage;
  }
  if (flags.geometry == "probe" && !app->count("--probe-radius-m")) {
    std::fprintf(
        stderr,
        "cellflow: --probe-radius-m must be given for --geometry probe (the colloidal probe's radius)\n");
    return ExitCode::kExitUsage;
  }
  if (flags.geometry == "tip" && !app->count("--tip-radius-m")) {
    std::fprintf(stderr,
                 "cellflow: --tip-radius-m must be given for --geometry tip (the tip's apex radius)\n");
    return ExitCode::kExitUsage;
  }
  v1::SubmitJobRequest request;
  v1::JobSpec* spec = request.mutable_spec();
  spec->set_name(flags.name.empty() ? "fit of " + std::to_string(flags.files.size()) + " curves"
                                    : flags.name);
  v1::FitSpec* fit = spec->mutable_fit();
  fit->set_geometry(flags.geometry == "plates"  ? v1::FIT_GEOMETRY_PLATES
                    : flags.geometry == "probe" ? v1::FIT_GEOMETRY_PROBE
                                                : v1::FIT_GEOMETRY_TIP);
  fit->set_radius_m(flags.radius_m);
  if (app->count("--probe-radius-m")) fit->set_probe_radius_m(flags.probe_radius_m);
  if (app->count("--tip-radius-m")) fit->set_tip_radius_m(flags.tip_radius_m);
  fit->set_model(flags.model == "hertz"         ? v1::FIT_MODEL_HERTZ
                 : flags.model == "neo-hookean" ? v1::FIT_MODEL_NEO_HOOKEAN
                                                : v1::FIT_MODEL_MOONEY_RIVLIN);
  if (flags.w_free) {
    fit->set_w_free(true);
  } else if (app->count("--w") || flags.model == "mooney-rivlin") {
    fit->set_mooney_rivlin_w(flags.w);
  }
  if (app->count("--poisson-ratio")) fit->set_poisson_ratio(flags.poisson_ratio);
  if (!flags.range.empty()) {
    const auto colon = flags.range.find(':');
    char* end1 = nullptr;
    char* end2 = nullptr;
    const double lo = colon == std::string::npos ? 0 : std::strtod(flags.range.c_str(), &end1);
    const double hi = colon == std::string::npos ? 0 : std::strtod(flags.range.c_str() + colon + 1, &end2);
    if (colon == std::string::npos || end1 != flags.range.c_str() + colon || end2 == nullptr ||
        *end2 != '\0') {
      std::fprintf(stderr, "cellflow: --range %s: give MIN:MAX, e.g. 0:0.5\n", flags.range.c_str());
      return ExitCode::kExitUsage;
    }
    fit->mutable_range()->set_mode(flags.range_unit == "m" ? v1::FitRange::RELATIVE_M
                                                           : v1::FitRange::DEFORMATION);
    fit->mutable_range()->set_min(lo);
    fit->mutable_range()->set_max(hi);
  }
  if (app->count("--vertices")) fit->mutable_numerics()->set_target_vertex_count(flags.vertices);
  if (app->count("--load-points")) fit->mutable_numerics()->set_load_points(flags.load_points);
  if (app->count("--library-max-deformation"))
    fit->mutable_numerics()->set_max_deformation(flags.library_max_deformation);
  if (app->count("--contact-window-radii")) fit->set_contact_window_radii(flags.contact_window_radii);
  if (flags.no_per_curve) fit->set_per_curve(false);
  if (flags.no_joint) fit->set_joint(false);

  // Every file read and checked here, before anything is submitted.
  client::FitInputOptions input_options;
  if (app->count("--spring-constant")) input_options.spring_constant_n_per_m = flags.spring_constant;
  if (app->count("--sensitivity")) input_options.sensitivity_m_per_v = flags.sensitivity;
  input_options.contact_at_zero = flags.contact_at_zero;
  std::vector<client::FitInputCurve> inputs;
  client::FitReport report;
  for (const std::string& file : flags.files) {
    StatusOr<client::FitInputCurve> input = client::read_fit_curve(file, flags.radius_m, input_options);
    if (!input.ok()) {
      std::fprintf(stderr, "cellflow: %s\n", input.status().message().c_str());
      return ExitCode::kExitInvalidArgument;
    }
    *fit->add_curves() = input->curve;
    report.files.push_back(file);
    report.contact_estimates_m.push_back(input->contact_estimate_m);
    inputs.push_back(std::move(*input));
  }
  if (Status s = client::check_fit_spec(*fit, inputs); !s.ok()) {
    std::fprintf(stderr, "cellflow: %s\n", s.message().c_str());
    return ExitCode::kExitInvalidArgument;
  }

  if (flags.print_spec) {
    std::printf("%s\n", jobs::job_spec_to_json(*spec).c_str());
    return ExitCode::kExitOk;
  }
  request.set_request_id(flags.request_id.empty() ? random_request_id() : flags.request_id);
  v1::SubmitJobResponse response;
  grpc::Status status = client.submit(request, &response);
  if (!status.ok()) return report_error(status, "submit");
  const std::string job_id = response.job().id();
  report.job_id = job_id;
  if (!flags.json) std::printf("%s\n", job_id.c_str());
  std::fflush(stdout);
  // Wait for the end (printing the events with --watch; progress to stderr otherwise).
  const bool terminal = ::isatty(STDOUT_FILENO) != 0;
  client::WatchPrinter printer(flags.json ? stderr : stdout, terminal);
  v1::Job::State last = v1::Job::STATE_UNSPECIFIED;
  std::string reason;
  status = client.watch(job_id, 0, [&](const v1::JobEvent& event) {
    if (flags.watch) printer.print(event);
    if (event.has_state_change()) {
      last = event.state_change().state();
      reason = event.state_change().reason();
    }
    return true;
  });
  if (flags.watch) printer.finish();
  if (!status.ok()) return report_error(status, "watch " + job_id);
  if (last != v1::Job::SUCCEEDED) {
    std::fprintf(stderr, "cellflow: %s %s: %s\n", job_id.c_str(), v1::Job::State_Name(last).c_str(),
                 reason.c_str());
    return client::exit_code_for(last);
  }
  TemporaryResult temporary;
  temporary.path =
      (fs::temp_directory_path() / ("cellflow-" + job_id + "-" + std::to_string(::getpid()) + ".h5"))
          .string();
  status = client.download(job_id, temporary.path);
  if (!status.ok()) return report_error(status, "result " + job_id);
  StatusOr<std::string> fit_json = client::read_fit_json(temporary.path);
  if (!fit_json.ok()) {
    std::fprintf(stderr, "cellflow: %s: %s\n", job_id.c_str(), fit_json.status().to_string().c_str());
    return ExitCode::kExitNotFound;
  }
  StatusOr<std::string> text =
      flags.json ? client::fit_json_report(*fit_json, report) : client::fit_table(*fit_json, report);
  if (!text.ok()) {
    std::fprintf(stderr, "cellflow: %s: %s\n", job_id.c_str(), text.status().to_string().c_str());
    return ExitCode::kExitFailed;
  }
  std::printf("%s%s", text->c_str(), flags.json ? "\n" : "");
  return ExitCode::kExitOk;
}

// The children of study `study_id`, in point order (every page).
grpc::Status list_children(client::Client& client, const std::string& study_id,
                           std::vector<v1::Job>* children) {
  v1::ListJobsRequest request;
  request.set_parent_job_id(study_id);
  request.set_page_size(1000);
  do {
    v1::ListJobsResponse response;
    const grpc::Status status = client.list(request, &response);
    if (!status.ok()) return status;
    for (const auto& job : response.jobs()) children->push_back(job);
    request.set_page_token(response.next_page_token());
  } while (!request.page_token().empty());
  std::sort(children->begin(), children->end(),
            [](const v1::Job& a, const v1::Job& b) { return a.child_index() < b.child_index(); });
  return grpc::Status::OK;
}

// "youngsModulusPa=1000, maxDeformation=0.2": a child's point, the last part of each path.
std::string point_label(const v1::StudySpec& study, int child_index) {
  std::string label;
  for (int a = 0; a < study.axes_size(); ++a) {
    const std::string& path = study.axes(a).path();
    const int k = client::study_value_index(study, child_index, a);
    if (k < 0 || k >= study.axes(a).values_size()) continue;
    label += (label.empty() ? "" : ", ") + path.substr(path.rfind('.') + 1) + "=" + study.axes(a).values(k);
  }
  return label;
}

// `cellflow plot STUDY`: the children's force curves overlaid (quasi-static)
// or their steady D against the first axis' value (shear flow).
int plot_study(client::Client& client, const v1::Job& study_job, const std::string& output) {
  const v1::StudySpec& study = study_job.spec().study();
  std::vector<v1::Job> children;
  if (grpc::Status status = list_children(client, study_job.id(), &children); !status.ok())
    return report_error(status, "list children of " + study_job.id());
  std::vector<client::LabelledCurve> curves;
  std::vector<client::SweptSteadyPoint> swept;
  std::vector<client::SteadyPoint> by_ca;
  std::vector<client::SuspensionPoint> suspensions;
  const std::string first_path = study.axes_size() > 0 ? study.axes(0).path() : "";
  const bool against_ca = first_path.ends_with("capillaryNumber") || first_path.ends_with("capillary_number");
  bool flow = false;
  for (const v1::Job& child : children) {
    if (child.state() != v1::Job::SUCCEEDED) {
      std::fprintf(stderr, "cellflow: %s (point %d) is %s: not plotted\n", child.id().c_str(),
                   child.child_index(), v1::Job::State_Name(child.state()).c_str());
      continue;
    }
    TemporaryResult temporary;
    temporary.path =
        (fs::temp_directory_path() / ("cellflow-" + child.id() + "-" + std::to_string(::getpid()) + ".h5"))
            .string();
    if (grpc::Status status = client.download(child.id(), temporary.path); !status.ok())
      return report_error(status, "result " + child.id());
    const std::string label = point_label(study, child.child_index());
    if (client::is_suspension_result(temporary.path)) {
      auto point = client::read_suspension_point(temporary.path, label);
      if (!point.ok()) {
        std::fprintf(stderr, "cellflow: %s: %s\n", child.id().c_str(), point.status().to_string().c_str());
        return ExitCode::kExitNotFound;
      }
      std::printf("%s  %s  Ca %.6g  phi %.4g  mean D %.6g +- %.2g  relative viscosity %.6g +- %.2g  (%s)\n",
                  child.id().c_str(), label.c_str(), point->capillary_number, point->volume_fraction,
                  point->average_taylor_deformation, point->average_taylor_deformation_error,
                  point->average_relative_viscosity, point->average_relative_viscosity_error,
                  point->stop.c_str());
      suspensions.push_back(std::move(*point));
    } else if (client::is_flow_result(temporary.path)) {
      flow = true;
      auto point = client::read_steady_point(temporary.path, label);
      if (!point.ok()) {
        std::fprintf(stderr, "cellflow: %s: %s\n", child.id().c_str(), point.status().to_string().c_str());
        return ExitCode::kExitNotFound;
      }
      const int k = client::study_value_index(study, child.child_index(), 0);
      const double value = std::strtod(study.axes(0).values(k).c_str(), nullptr);
      swept.push_back({value, point->steady_taylor_deformation, point->stop == "steady"});
      by_ca.push_back(*point);
      std::printf("%s  %s  steady D %.6g  (%s)\n", child.id().c_str(), label.c_str(),
                  point->steady_taylor_deformation, point->stop.c_str());
    } else {
      auto curve = client::read_curve(temporary.path);
      if (!curve.ok()) {
        std::fprintf(stderr, "cellflow: %s: %s\n", child.id().c_str(), curve.status().to_string().c_str());
        return ExitCode::kExitNotFound;
      }
      curves.push_back({label, std::move(*curve)});
    }
  }
  if (curves.empty() && swept.empty() && suspensions.empty()) {
    std::fprintf(stderr, "cellflow: %s has no succeeded child to plot\n", study_job.id().c_str());
    return ExitCode::kExitNotFound;
  }
  const std::string title =
      study_job.id() + " (study of " + std::to_string(study_job.child_count()) + " children)";
  // A suspension study: against the volume fraction when the first axis sweeps
  // a kind's (suspension.cells[k].volumeFraction), else against Ca.
  const bool phi_axis = first_path.ends_with("volumeFraction") || first_path.ends_with("volume_fraction");
  const std::string text = !suspensions.empty() ? client::suspension_points_svg(
                                                      suspensions,
                                                      phi_axis ? client::SuspensionAxis::kVolumeFraction
                                                               : client::SuspensionAxis::kCapillaryNumber,
                                                      title)
                           : !flow      ? client::curves_overlay_svg(curves, title)
                           : against_ca ? client::steady_deformation_svg(by_ca, title)
                                        : client::swept_steady_svg(swept, first_path, title);
  if (!client::write_output(output, text)) {
    std::fprintf(stderr, "cellflow: cannot write %s\n", output.c_str());
    return ExitCode::kExitUsage;
  }
  if (!client::is_stdout_name(output)) std::printf("%s\n", output.c_str());
  return ExitCode::kExitOk;
}

// After a parse error: the first word of the command line that names no
// subcommand or option where it stands, and the known one nearest it
// ("unknown subcommand 'lsit'; did you mean 'list'?"); "" when every word is
// known (the error is another one: a missing value, a bad number, ...).
std::string did_you_mean(CLI::App& root, int argc, char** argv) {
  CLI::App* current = &root;
  for (int i = 1; i < argc; ++i) {
    const std::string token = argv[i];
    if (token == "--") break;
    if (token.size() > 1 && token[0] == '-') {
      const std::string name = token.substr(0, token.find('='));
      const CLI::Option* option = nullptr;
      // Options of the enclosing commands count too (fallthrough).
      for (CLI::App* a = current; a != nullptr && option == nullptr; a = a->get_parent())
        option = a->get_option_no_throw(name);
      if (option == nullptr) {
        std::vector<std::string> names;
        for (CLI::App* a = current; a != nullptr; a = a->get_parent()) {
          for (const CLI::Option* o : a->get_options()) {
            for (const std::string& l : o->get_lnames()) names.push_back("--" + l);
            for (const std::string& n : o->get_snames()) names.push_back("-" + n);
          }
        }
        const std::string guess = client::closest_word(name, names);
        const std::string where = current == &root ? "" : " of " + current->get_name();
        return "unknown option '" + name + "'" + where +
               (guess.empty() ? "" : "; did you mean '" + guess + "'?");
      }
      if (token.find('=') == std::string::npos && option->get_items_expected_max() > 0) ++i;  // its value
      continue;
    }
    const auto subcommands = current->get_subcommands([&](CLI::App* s) { return s->check_name(token); });
    if (!subcommands.empty()) {
      current = subcommands.front();
      continue;
    }
    const auto all = current->get_subcommands([](CLI::App*) { return true; });
    const bool positionals =
        !current->get_options([](const CLI::Option* o) { return o->get_positional(); }).empty();
    if (!all.empty() && !positionals) {
      std::vector<std::string> names;
      for (const CLI::App* s : all) names.push_back(s->get_name());
      const std::string guess = client::closest_word(token, names);
      std::string known;
      for (const std::string& n : names) known += (known.empty() ? "" : ", ") + n;
      return "unknown subcommand '" + token + "'" + (current == &root ? "" : " of " + current->get_name()) +
             (guess.empty() ? "; the subcommands are " + known : "; did you mean '" + guess + "'?");
    }
  }
  return "";
}

// `cellflow completion bash`: a completion function that walks the words
// typed so far through the subcommands and offers the subcommands and flags
// of the innermost one (with the global flags, which work after it too).
void add_completion_cases(const CLI::App& app, const std::string& path, const std::string& global,
                          std::string& walk, std::string& offer) {
  std::string words;
  const auto subcommands = app.get_subcommands([](const CLI::App*) { return true; });
  for (const CLI::App* sub : subcommands) words += sub->get_name() + " ";
  for (const CLI::Option* option : app.get_options()) {
    for (const std::string& l : option->get_lnames()) words += "--" + l + " ";
    for (const std::string& n : option->get_snames()) words += "-" + n + " ";
  }
  if (!path.empty()) words += global;
  while (!words.empty() && words.back() == ' ') words.pop_back();
  offer += "    \"" + path + "\") words=\"" + words + "\" ;;\n";
  for (const CLI::App* sub : subcommands) {
    const std::string sub_path = path + " " + sub->get_name();
    walk += "      \"" + sub_path + "\") path=\"$path $w\" ;;\n";
    add_completion_cases(*sub, sub_path, global, walk, offer);
  }
}

std::string bash_completion(const CLI::App& app) {
  std::string global;
  for (const CLI::Option* option : app.get_options()) {
    // --help is each command's own, --version the top level's only.
    if (option->get_lnames() == std::vector<std::string>{"help"} ||
        option->get_lnames() == std::vector<std::string>{"version"})
      continue;
    for (const std::string& l : option->get_lnames()) global += "--" + l + " ";
  }
  std::string walk, offer;
  add_completion_cases(app, "", global, walk, offer);
  return "# bash completion for cellflow: source <(cellflow completion bash)\n"
         "_cellflow() {\n"
         "  local cur=\"${COMP_WORDS[COMP_CWORD]}\" path=\"\" w i words=\"\"\n"
         "  for ((i = 1; i < COMP_CWORD; i++)); do\n"
         "    w=\"${COMP_WORDS[i]}\"\n"
         "    case \"$path $w\" in\n" +
         walk +
         "    esac\n"
         "  done\n"
         "  case \"$path\" in\n" +
         offer +
         "  esac\n"
         "  COMPREPLY=($(compgen -W \"$words\" -- \"$cur\"))\n"
         "}\n"
         "complete -o default -F _cellflow cellflow\n";
}

}  // namespace

int main(int argc, char** argv) {
  client::ClientOptions options;
  if (const char* env = std::getenv("CELLFLOW_SERVER")) options.server = env;

  CLI::App app{"cellflow: submit, follow and fetch cell-mechanics simulations of a cellflow server."};
  app.footer(client::kExitCodeHelp);
  app.set_version_flag("--version",
                       std::string("cellflow ") + client::kVersion + " (commit " + client::kGitCommit + ")");
  app.require_subcommand(1);
  app.fallthrough();  // --server and --timeout-s also after the subcommand
  app.add_option("--server", options.server, "server address host:port (env CELLFLOW_SERVER)")
      ->capture_default_str();
  app.add_option("--timeout-s", options.timeout_s, "deadline of each call")->capture_default_str();
  client::CredentialSources credentials;
  app.add_option("--token-file", credentials.token_file,
                 "file holding the API token, mode 0600 (default: env CELLFLOW_TOKEN, else "
                 "~/.config/cellflow/token if present)");
  app.add_option("--tls-ca", credentials.tls_ca_file,
                 "CA certificate (PEM) that signed the server's certificate: use TLS (env CELLFLOW_TLS_CA)");
  app.add_option("--tls-cert", credentials.tls_cert_file,
                 "client certificate (PEM) for mTLS (env CELLFLOW_TLS_CERT)");
  app.add_option("--tls-key", credentials.tls_key_file, "client key (PEM) for mTLS (env CELLFLOW_TLS_KEY)");
  app.add_option("--tls-server-name", options.tls_server_name,
                 "name to check the server's certificate against (default: the host of --server)");

  // submit
  auto* submit = app.add_subcommand("submit", "submit a job from flags or from a JSON spec");
  std::string spec_file, request_id, name;
  bool submit_watch = false, print_json = false;
  submit->add_option(
      "--spec", spec_file,
      "job spec as JSON (protobuf JSON mapping of cellflow.v1.JobSpec): a file, - for stdin, or "
      "the JSON itself ('{...}')");
  submit->add_option("--request-id", request_id, "idempotency key: the same id twice gives the same job");
  submit->add_option("--name", name, "a name for the job");
  submit->add_flag("--watch", submit_watch, "follow the job until it ends; exit with its state's code");
  submit->add_flag("--json", print_json, "print the job as JSON");
  std::vector<std::string> submit_sets;
  submit
      ->add_option("--set", submit_sets,
                   "PATH=VALUE: set a field of the spec before submitting (protobuf JSON path, e.g. "
                   "compression.loadPoints=20; repeatable)")
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  submit->require_subcommand(0, 1);
  submit->fallthrough();

  CellFlags compression_cell;
  double max_deformation = 0;
  int compression_points = 0;
  auto* compression = submit->add_subcommand("compression", "a cell compressed between two plates");
  compression_cell.add(compression);
  compression->add_option("--max-deformation", max_deformation, "final compression / diameter, in (0, 0.9]")
      ->required();
  compression->add_option("--load-points", compression_points, "points of the curve (server default 40)");

  CellFlags indentation_cell;
  double probe_radius_m = 0, max_indentation_m = 0;
  int indentation_points = 0;
  auto* indentation = submit->add_subcommand("indentation", "a spherical probe indenting a cell on a plate");
  indentation_cell.add(indentation);
  indentation->add_option("--probe-radius-m", probe_radius_m, "probe radius in metres")->required();
  indentation->add_option("--max-indentation-m", max_indentation_m, "probe travel after contact, metres")
      ->required();
  indentation->add_option("--load-points", indentation_points, "points of the curve (server default 40)");

  CellFlags flow_cell;
  double capillary_number = 0, shear_rate_per_s = 0, fluid_viscosity_pa_s = 0, fluid_density_kg_m3 = 0;
  double cells_per_radius = 0, max_strain = 0, max_time_s = 0, sample_every_strain = 0;
  bool fluid_snapshots = false;
  auto* shear_flow = submit->add_subcommand("shear-flow", "a cell in plane shear flow (paper section 7.1)");
  flow_cell.add(shear_flow);
  auto* ca_option = shear_flow->add_option("--capillary-number", capillary_number,
                                           "Ca = eta gammadot / mu (paper eq. 17), in [1e-6, 100]");
  auto* rate_option = shear_flow->add_option("--shear-rate-per-s", shear_rate_per_s,
                                             "shear rate gammadot in 1/s (instead of Ca)");
  ca_option->excludes(rate_option);
  shear_flow->add_option("--fluid-viscosity-pa-s", fluid_viscosity_pa_s, "eta (server default 1e-3, water)");
  shear_flow->add_option("--fluid-density-kg-m3", fluid_density_kg_m3, "rho (server default 1000)");
  shear_flow->add_option("--cells-per-radius", cells_per_radius,
                         "lattice resolution R / dx (server default 6)");
  shear_flow->add_option("--max-strain", max_strain, "stop at this strain gammadot t (server default 40)");
  shear_flow->add_option("--max-time-s", max_time_s,
                         "stop at this simulated time (server default: no limit)");
  shear_flow->add_option("--sample-every-strain", sample_every_strain,
                         "a deformation sample every this much strain (server default 0.1)");
  shear_flow->add_flag("--fluid-snapshots", fluid_snapshots, "keep the fluid velocity at the snapshots");

  // sweep
  std::string sweep_spec_file;
  std::vector<std::string> sweep_sets;
  bool sweep_zip = false;
  auto* sweep = app.add_subcommand(
      "sweep",
      "submit one study: a base spec expanded over --set PATH=V1,V2,... (the outer product of the axes; "
      "--zip: "
      "taken together); any worker runs its children; watch, cancel, list and plot it as one job");
  sweep->add_option("--spec", sweep_spec_file, "the base job spec as JSON: a file, - for stdin, or '{...}'")
      ->required();
  sweep
      ->add_option("--set", sweep_sets,
                   "PATH=V1,V2,...: sweep a field of the base spec (protobuf JSON path, e.g. "
                   "shearFlow.capillaryNumber=0.05,0.1,0.2; repeatable: one axis each)")
      ->required()
      ->expected(1)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  sweep->add_flag("--zip", sweep_zip,
                  "take the axes together point by point (equal lengths) instead of the grid");
  sweep->add_option("--request-id", request_id, "idempotency key: the same id twice gives the same study");
  sweep->add_option("--name", name, "a name for the study");
  sweep->add_flag("--watch", submit_watch, "follow the study until its last child ends");
  sweep->add_flag("--json", print_json, "print the study as JSON");

  // watch, get, list, cancel, result, plot
  std::string job_id, output;
  std::int64_t after_sequence = 0;
  bool quiet = false, csv = false;
  auto* watch_cmd = app.add_subcommand("watch", "follow a job live: samples, progress, state changes");
  watch_cmd->add_option("job", job_id, "job id (job-<n>)")->required();
  watch_cmd->add_option("--after", after_sequence, "resume after this event sequence number");
  watch_cmd->add_flag("--quiet", quiet, "print state changes only");

  auto* get = app.add_subcommand("get", "show a job");
  get->add_option("job", job_id, "job id")->required();
  get->add_flag("--json", print_json, "print the job as JSON");

  std::string state_name;
  int page_size = 0;
  auto* list = app.add_subcommand("list", "list jobs, oldest first");
  list->add_option("--state", state_name, "only jobs in this state")
      ->check(CLI::IsMember({"QUEUED", "RUNNING", "SUCCEEDED", "FAILED", "CANCELLED"}, CLI::ignore_case));
  list->add_option("--page-size", page_size, "jobs per request");
  std::string list_parent;
  list->add_option("--parent", list_parent, "only the children of this study");
  bool list_json = false;
  list->add_flag("--json", list_json,
                 "print the jobs as one JSON array (protobuf JSON mapping of cellflow.v1.Job)");

  auto* cancel = app.add_subcommand("cancel", "cancel a queued or running job");
  cancel->add_option("job", job_id, "job id")->required();

  auto* delete_cmd =
      app.add_subcommand("delete", "delete a finished job: its record, events and result file");
  delete_cmd->add_option("job", job_id, "job id")->required();

  auto* result =
      app.add_subcommand("result", "fetch a job's result: the HDF5 file (+ XDMF) or the curve as CSV");
  result->add_option("job", job_id, "job id")->required();
  result->add_option("-o,--output", output,
                     "output file (.h5; with --csv: .csv, default stdout); - for stdout");
  result->add_flag("--csv", csv,
                   "the force-deformation curve (compression, indentation) or the deformation time series "
                   "D(t) (shear flow) as CSV");

  std::vector<std::string> plot_jobs;
  std::string against;
  auto* plot = app.add_subcommand(
      "plot",
      "draw a job's result as SVG: force against deformation with Hertz (compression, indentation), D "
      "against strain (shear flow), mean D against strain with the band over the cells (suspension); with "
      "--against capillary-number the steady D of several shear-flow jobs against Ca beside Roscoe's theory, "
      "or of several suspension jobs the averaged mean D and relative viscosity against Ca or "
      "(--against volume-fraction) the volume fraction");
  plot->add_option("jobs", plot_jobs, "job id(s)")->required();
  plot->add_option("-o,--output", output, "SVG file (.svg), - for stdout")->required();
  plot->add_option(
          "--against", against,
          "steady D (shear flow) or averaged mean D and relative viscosity (suspension) of the given "
          "jobs against this quantity (volume-fraction: suspensions only)")
      ->check(CLI::IsMember({"capillary-number", "volume-fraction"}));

  FitFlags fit_flags;
  auto* fit_cmd = app.add_subcommand(
      "fit",
      "fit E and the Mooney-Rivlin ratio w (with 95 % intervals) to measured force curves: the files are "
      "read "
      "here and sent as data; the server's worker fits them with the compression or indentation scene");
  fit_flags.add(fit_cmd);

  std::string completion_shell;
  auto* completion =
      app.add_subcommand("completion", "print a shell completion script: source <(cellflow completion bash)");
  completion->add_option("shell", completion_shell, "the shell (bash)")
      ->required()
      ->check(CLI::IsMember({"bash"}));

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() != 0) {  // not --help or --version
      if (const std::string hint = did_you_mean(app, argc, argv); !hint.empty()) {
        std::fprintf(stderr, "cellflow: %s\nRun with --help for more information.\n", hint.c_str());
        return ExitCode::kExitUsage;
      }
    }
    const int code = app.exit(e);
    return code == 0 ? ExitCode::kExitOk : ExitCode::kExitUsage;
  }

  if (completion->parsed()) {
    std::printf("%s", bash_completion(app).c_str());
    return ExitCode::kExitOk;
  }

  // An output name whose extension is not the format written is refused before anything is fetched.
  if (result->parsed() || plot->parsed()) {
    const std::string error = plot->parsed() ? client::check_output_name(output, "SVG", {".svg"})
                              : csv          ? client::check_output_name(output, "CSV", {".csv"})
                                             : client::check_output_name(output, "HDF5", {".h5", ".hdf5"});
    if (!error.empty()) {
      std::fprintf(stderr, "cellflow: %s\n", error.c_str());
      return ExitCode::kExitUsage;
    }
  }
  const bool to_stdout = client::is_stdout_name(output);

  if (const std::string error = client::load_credentials(credentials, &options); !error.empty()) {
    std::fprintf(stderr, "cellflow: %s\n", error.c_str());
    return ExitCode::kExitUsage;
  }
  client::Client client(options);

  if (submit->parsed()) {
    v1::SubmitJobRequest request;
    if (!spec_file.empty()) {
      if (compression->parsed() || indentation->parsed() || shear_flow->parsed()) {
        std::fprintf(stderr, "cellflow: give either --spec or a scene, not both\n");
        return ExitCode::kExitUsage;
      }
      const client::SpecText text = client::read_spec_arg(spec_file, std::cin);
      if (!text.error.empty()) {
        std::fprintf(stderr, "cellflow: %s\n", text.error.c_str());
        return ExitCode::kExitUsage;
      }
      // The parser of the server and cellflow-run: the same fields, the same errors.
      StatusOr<v1::JobSpec> parsed = jobs::job_spec_from_json(text.text);
      if (!parsed.ok()) {
        std::fprintf(stderr, "cellflow: %s: %s\n", text.source.c_str(), parsed.status().message().c_str());
        return ExitCode::kExitInvalidArgument;
      }
      *request.mutable_spec() = std::move(*parsed);
    } else if (compression->parsed()) {
      auto* spec = request.mutable_spec()->mutable_compression();
      compression_cell.fill(compression, spec->mutable_cell());
      spec->set_max_deformation(max_deformation);
      if (compression->count("--load-points")) spec->set_load_points(compression_points);
    } else if (indentation->parsed()) {
      auto* spec = request.mutable_spec()->mutable_indentation();
      indentation_cell.fill(indentation, spec->mutable_cell());
      spec->set_probe_radius_m(probe_radius_m);
      spec->set_max_indentation_m(max_indentation_m);
      if (indentation->count("--load-points")) spec->set_load_points(indentation_points);
    } else if (shear_flow->parsed()) {
      if (!shear_flow->count("--capillary-number") && !shear_flow->count("--shear-rate-per-s")) {
        std::fprintf(stderr, "cellflow: submit shear-flow needs --capillary-number or --shear-rate-per-s\n");
        return ExitCode::kExitUsage;
      }
      auto* spec = request.mutable_spec()->mutable_shear_flow();
      flow_cell.fill(shear_flow, spec->mutable_cell());
      if (shear_flow->count("--capillary-number")) spec->set_capillary_number(capillary_number);
      if (shear_flow->count("--shear-rate-per-s")) spec->set_shear_rate_per_s(shear_rate_per_s);
      if (shear_flow->count("--fluid-viscosity-pa-s")) spec->set_fluid_viscosity_pa_s(fluid_viscosity_pa_s);
      if (shear_flow->count("--fluid-density-kg-m3")) spec->set_fluid_density_kg_m3(fluid_density_kg_m3);
      auto* numerics = spec->mutable_numerics();
      if (shear_flow->count("--cells-per-radius")) numerics->set_cells_per_radius(cells_per_radius);
      if (shear_flow->count("--max-strain")) numerics->set_max_strain(max_strain);
      if (shear_flow->count("--max-time-s")) numerics->set_max_time_s(max_time_s);
      if (shear_flow->count("--sample-every-strain")) numerics->set_sample_every_strain(sample_every_strain);
      if (fluid_snapshots) numerics->set_fluid_snapshots(true);
    } else {
      std::fprintf(stderr,
                   "cellflow: submit needs --spec FILE.json|-|'{...}' or a scene (compression, indentation, "
                   "shear-flow)\n");
      return ExitCode::kExitUsage;
    }
    // --set edits the spec with the parser of the server: a wrong path or value names the --set.
    for (const std::string& set : submit_sets) {
      StatusOr<v1::JobSpec> edited = client::apply_set(request.spec(), set);
      if (!edited.ok()) {
        std::fprintf(stderr, "cellflow: %s\n", edited.status().message().c_str());
        return ExitCode::kExitInvalidArgument;
      }
      *request.mutable_spec() = std::move(*edited);
    }
    if (!name.empty()) request.mutable_spec()->set_name(name);
    if (const int uploaded = upload_mesh_file(client, *request.mutable_spec()); uploaded != ExitCode::kExitOk)
      return uploaded;
    // Retries of an unanswered submit must not create a second job.
    request.set_request_id(request_id.empty() ? random_request_id() : request_id);
    v1::SubmitJobResponse response;
    const grpc::Status status = client.submit(request, &response);
    if (!status.ok()) return report_error(status, "submit");
    if (print_json) {
      std::printf("%s\n", to_json(response.job()).c_str());
    } else {
      std::printf("%s%s\n", response.job().id().c_str(),
                  response.already_existed() ? " (already submitted)" : "");
    }
    std::fflush(stdout);
    if (submit_watch) return watch(client, response.job().id(), 0, false);
    return ExitCode::kExitOk;
  }

  if (sweep->parsed()) {
    const client::SpecText text = client::read_spec_arg(sweep_spec_file, std::cin);
    if (!text.error.empty()) {
      std::fprintf(stderr, "cellflow: %s\n", text.error.c_str());
      return ExitCode::kExitUsage;
    }
    StatusOr<v1::JobSpec> base = jobs::job_spec_from_json(text.text);
    if (!base.ok()) {
      std::fprintf(stderr, "cellflow: %s: %s\n", text.source.c_str(), base.status().message().c_str());
      return ExitCode::kExitInvalidArgument;
    }
    if (const int uploaded = upload_mesh_file(client, *base); uploaded != ExitCode::kExitOk) return uploaded;
    v1::SubmitJobRequest request;
    v1::StudySpec* study = request.mutable_spec()->mutable_study();
    *study->mutable_base() = std::move(*base);
    for (const std::string& set : sweep_sets) {
      StatusOr<v1::StudyAxis> axis = client::parse_set_axis(set);
      if (!axis.ok()) {
        std::fprintf(stderr, "cellflow: %s\n", axis.status().message().c_str());
        return ExitCode::kExitUsage;
      }
      *study->add_axes() = std::move(*axis);
    }
    study->set_combination(sweep_zip ? v1::StudySpec::ZIP : v1::StudySpec::GRID);
    request.mutable_spec()->set_name(name.empty() ? study->base().name() : name);
    request.set_request_id(request_id.empty() ? random_request_id() : request_id);
    v1::SubmitJobResponse response;
    const grpc::Status status = client.submit(request, &response);
    if (!status.ok()) return report_error(status, "sweep");
    if (print_json) {
      std::printf("%s\n", to_json(response.job()).c_str());
    } else {
      std::printf("%s%s (%d children)\n", response.job().id().c_str(),
                  response.already_existed() ? " (already submitted)" : "", response.job().child_count());
    }
    std::fflush(stdout);
    if (submit_watch) return watch(client, response.job().id(), 0, false);
    return ExitCode::kExitOk;
  }

  if (fit_cmd->parsed()) return run_fit(client, fit_cmd, fit_flags);

  if (watch_cmd->parsed()) return watch(client, job_id, after_sequence, quiet);

  if (get->parsed()) {
    v1::Job job;
    const grpc::Status status = client.get(job_id, &job);
    if (!status.ok()) return report_error(status, "get " + job_id);
    if (print_json) {
      std::printf("%s\n", to_json(job).c_str());
    } else {
      print_job(job);
      std::printf("  created %s  started %s  ended %s\n", time_string(job.create_time()).c_str(),
                  time_string(job.start_time()).c_str(), time_string(job.end_time()).c_str());
      if (job.state() == v1::Job::RUNNING && job.estimated_remaining_s() >= 0) {
        std::printf("  about %.0f s left\n", job.estimated_remaining_s());
      }
      if (job.result_size_bytes() > 0)
        std::printf("  result: %lld bytes\n", static_cast<long long>(job.result_size_bytes()));
    }
    return ExitCode::kExitOk;
  }

  if (list->parsed()) {
    v1::ListJobsRequest request;
    if (!state_name.empty()) {
      v1::Job::State state = v1::Job::STATE_UNSPECIFIED;
      for (auto& c : state_name) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
      v1::Job::State_Parse(state_name, &state);
      request.set_state(state);
    }
    request.set_page_size(page_size);
    request.set_parent_job_id(list_parent);
    // Every page fetched before anything is printed: an error leaves no half list.
    std::vector<v1::Job> jobs;
    do {
      v1::ListJobsResponse response;
      const grpc::Status status = client.list(request, &response);
      if (!status.ok()) return report_error(status, "list");
      for (const auto& job : response.jobs()) jobs.push_back(job);
      request.set_page_token(response.next_page_token());
    } while (!request.page_token().empty());
    if (list_json) {
      std::string array = "[";
      for (std::size_t i = 0; i < jobs.size(); ++i) {
        std::string job = to_json(jobs[i]);
        while (!job.empty() && job.back() == '\n') job.pop_back();
        array += (i == 0 ? "\n" : ",\n") + job;
      }
      array += jobs.empty() ? "]" : "\n]";
      std::printf("%s\n", array.c_str());
      return ExitCode::kExitOk;
    }
    std::printf("ID  STATE  SCENE  ATTEMPT  DONE  NAME  REASON\n");
    for (const auto& job : jobs) print_job(job);
    return ExitCode::kExitOk;
  }

  if (cancel->parsed()) {
    v1::Job job;
    const grpc::Status status = client.cancel(job_id, &job);
    if (!status.ok()) return report_error(status, "cancel " + job_id);
    print_job(job);
    return ExitCode::kExitOk;
  }

  if (delete_cmd->parsed()) {
    const grpc::Status status = client.delete_job(job_id);
    if (!status.ok()) return report_error(status, "delete " + job_id);
    std::printf("%s deleted\n", job_id.c_str());
    return ExitCode::kExitOk;
  }

  if (plot->parsed()) {
    if (plot_jobs.size() > 1 && against.empty()) {
      std::fprintf(stderr,
                   "cellflow: plot of several jobs needs --against capillary-number (or volume-fraction)\n");
      return ExitCode::kExitUsage;
    }
    job_id = plot_jobs.front();
    if (against.empty()) {
      v1::Job job;
      if (const grpc::Status status = client.get(job_id, &job); !status.ok())
        return report_error(status, "get " + job_id);
      if (job.spec().has_study()) return plot_study(client, job, output);
    }
  }

  if (plot->parsed() && !against.empty()) {
    std::vector<client::SteadyPoint> points;
    std::vector<client::SuspensionPoint> suspensions;
    for (const std::string& id : plot_jobs) {
      TemporaryResult temporary;
      temporary.path =
          (fs::temp_directory_path() / ("cellflow-" + id + "-" + std::to_string(::getpid()) + ".h5"))
              .string();
      const grpc::Status status = client.download(id, temporary.path);
      if (!status.ok()) return report_error(status, "result " + id);
      if (client::is_suspension_result(temporary.path)) {
        auto point = client::read_suspension_point(temporary.path, id);
        if (!point.ok()) {
          std::fprintf(stderr, "cellflow: %s\n", point.status().to_string().c_str());
          return ExitCode::kExitNotFound;
        }
        suspensions.push_back(std::move(*point));
        continue;
      }
      if (against == "volume-fraction") {
        std::fprintf(stderr,
                     "cellflow: %s is not a suspension: --against volume-fraction plots suspensions\n",
                     id.c_str());
        return ExitCode::kExitUsage;
      }
      auto point = client::read_steady_point(temporary.path, id);
      if (!point.ok()) {
        std::fprintf(stderr, "cellflow: %s\n", point.status().to_string().c_str());
        return ExitCode::kExitNotFound;
      }
      points.push_back(std::move(*point));
    }
    if (!suspensions.empty() && !points.empty()) {
      std::fprintf(stderr, "cellflow: plot either shear-flow or suspension jobs together, not both\n");
      return ExitCode::kExitUsage;
    }
    if (!suspensions.empty()) {
      const auto axis = against == "volume-fraction" ? client::SuspensionAxis::kVolumeFraction
                                                     : client::SuspensionAxis::kCapillaryNumber;
      const std::string text = client::suspension_points_svg(
          suspensions, axis,
          "suspensions: mean D and relative viscosity against " +
              std::string(axis == client::SuspensionAxis::kVolumeFraction ? "volume fraction" : "Ca") + " (" +
              std::to_string(suspensions.size()) + " jobs)");
      if (!client::write_output(output, text)) {
        std::fprintf(stderr, "cellflow: cannot write %s\n", output.c_str());
        return ExitCode::kExitUsage;
      }
      for (const auto& p : suspensions) {
        std::fprintf(to_stdout ? stderr : stdout,
                     "%s  Ca %.6g  phi %.4g  mean D %.6g +- %.2g  relative viscosity %.6g +- %.2g  (%s)\n",
                     p.label.c_str(), p.capillary_number, p.volume_fraction, p.average_taylor_deformation,
                     p.average_taylor_deformation_error, p.average_relative_viscosity,
                     p.average_relative_viscosity_error, p.stop.c_str());
      }
      if (!to_stdout) std::printf("%s\n", output.c_str());
      return ExitCode::kExitOk;
    }
    const std::string text = client::steady_deformation_svg(
        points, "steady deformation against capillary number (" + std::to_string(points.size()) + " jobs)");
    if (!client::write_output(output, text)) {
      std::fprintf(stderr, "cellflow: cannot write %s\n", output.c_str());
      return ExitCode::kExitUsage;
    }
    // The summary on stdout beside a file, on stderr when stdout is the SVG.
    for (const auto& p : points) {
      std::fprintf(to_stdout ? stderr : stdout, "%s  Ca %.6g  steady D %.6g  (%s)\n", p.label.c_str(),
                   p.capillary_number, p.steady_taylor_deformation, p.stop.c_str());
    }
    if (!to_stdout) std::printf("%s\n", output.c_str());
    return ExitCode::kExitOk;
  }

  if (result->parsed() || plot->parsed()) {
    const bool want_file = result->parsed() && !csv;
    if (want_file && output.empty()) {
      std::fprintf(stderr, "cellflow: result needs -o FILE.h5 or --csv\n");
      return ExitCode::kExitUsage;
    }
    TemporaryResult temporary;
    std::string h5 = output;
    if (!want_file || to_stdout) {
      temporary.path =
          (fs::temp_directory_path() / ("cellflow-" + job_id + "-" + std::to_string(::getpid()) + ".h5"))
              .string();
      h5 = temporary.path;
    }
    const grpc::Status status = client.download(job_id, h5);
    if (!status.ok()) return report_error(status, "result " + job_id);
    if (want_file && to_stdout) {  // the HDF5 bytes themselves (no XDMF beside them)
      std::ifstream in(h5, std::ios::binary);
      std::ostringstream bytes;
      bytes << in.rdbuf();
      if (!in || !client::write_output(output, bytes.str())) {
        std::fprintf(stderr, "cellflow: cannot copy the result of %s to stdout\n", job_id.c_str());
        return ExitCode::kExitUsage;
      }
      return ExitCode::kExitOk;
    }
    if (want_file) {
      const std::string xdmf = (fs::path(h5).replace_extension(".xdmf")).string();
      if (Status s = io::write_xdmf(h5, xdmf); s.ok()) {
        std::printf("%s\n%s\n", h5.c_str(), xdmf.c_str());
      } else {
        std::printf("%s\n", h5.c_str());
        std::fprintf(stderr, "cellflow: no XDMF file: %s\n", s.to_string().c_str());
      }
      return ExitCode::kExitOk;
    }
    if (client::is_fit_result(h5)) {
      auto curves = client::read_fit_curves(h5);
      if (!curves.ok()) {
        std::fprintf(stderr, "cellflow: %s\n", curves.status().to_string().c_str());
        return ExitCode::kExitNotFound;
      }
      const std::string text = plot->parsed()
                                   ? client::fit_svg(*curves, job_id + " (fit: data, model, Hertz)")
                                   : client::fit_curves_csv(*curves);
      if (!client::write_output(output, text)) {
        std::fprintf(stderr, "cellflow: cannot write %s\n", output.c_str());
        return ExitCode::kExitUsage;
      }
      if (!output.empty() && !to_stdout) std::printf("%s\n", output.c_str());
      return ExitCode::kExitOk;
    }
    if (client::is_suspension_result(h5)) {
      auto series = client::read_suspension_series(h5);
      if (!series.ok()) {
        std::fprintf(stderr, "cellflow: %s\n", series.status().to_string().c_str());
        return ExitCode::kExitNotFound;
      }
      const std::string text =
          plot->parsed() ? client::suspension_svg(*series, job_id + " (suspension: mean D over the cells)")
                         : client::curve_csv(series->table);
      if (!client::write_output(output, text)) {
        std::fprintf(stderr, "cellflow: cannot write %s\n", output.c_str());
        return ExitCode::kExitUsage;
      }
      if (!output.empty() && !to_stdout) std::printf("%s\n", output.c_str());
      return ExitCode::kExitOk;
    }
    const bool flow = client::is_flow_result(h5);
    auto curve = flow ? client::read_deformation_series(h5) : client::read_curve(h5);
    if (!curve.ok()) {
      std::fprintf(stderr, "cellflow: %s\n", curve.status().to_string().c_str());
      return ExitCode::kExitNotFound;
    }
    std::string text;
    if (plot->parsed()) {
      v1::Job job;
      std::string title = job_id;
      if (client.get(job_id, &job).ok()) {
        title +=
            " (" + scene_of(job.spec()) + (job.spec().name().empty() ? "" : ", " + job.spec().name()) + ")";
      }
      if (flow) {
        auto point = client::read_steady_point(h5, job_id);
        text = client::deformation_svg(*curve, point.ok() ? point->capillary_number : 0.0,
                                       point.ok() ? point->steady_taylor_deformation : 0.0, title);
      } else {
        text = client::curve_svg(*curve, title);
      }
    } else {
      text = client::curve_csv(*curve);
    }
    if (!client::write_output(output, text)) {
      std::fprintf(stderr, "cellflow: cannot write %s\n", output.c_str());
      return ExitCode::kExitUsage;
    }
    if (!output.empty() && !to_stdout) std::printf("%s\n", output.c_str());
    return ExitCode::kExitOk;
  }
  return ExitCode::kExitUsage;
}
