// cellflow-make-fit-data: writes synthetic force curves for `cellflow fit`
// (examples/fit): the compression scene's curve (physics/calibration's curve
// library, the fit's own model) at a known E and w, with multiplicative
// Gaussian noise on the force and a contact point offset per curve. The
// curves are columns indentation_m,force_n, the indentation measured from a
// nominal contact; before the true contact the force is 0.
//
//   cellflow-make-fit-data --out-dir examples/fit --youngs-modulus-pa 150 --w 0.5
//     --radius-m 8.6e-6 --curves 5 --noise 0.03 --vertices 1000 --load-points 20 --seed 14
#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include "physics/calibration/curve_library.h"

int main(int argc, char** argv) {
  namespace cal = cellflow::calibration;
  std::string out_dir = "examples/fit", library_dir;
  double e = 150.0, w = 0.5, radius = 8.6e-6, noise = 0.03, max_deformation = 0.6, step_m = 0.05e-6;
  double offset_m = 0.4e-6, pre_contact_m = 8e-6;
  int curves = 5, vertices = 1000, load_points = 20;
  unsigned seed = 14;
  CLI::App app{"cellflow-make-fit-data: synthetic compression force curves of known E and w"};
  app.add_option("--out-dir", out_dir, "where the CSV files go")->capture_default_str();
  app.add_option("--youngs-modulus-pa", e, "true E")->capture_default_str();
  app.add_option("--w", w, "true Mooney-Rivlin ratio (a value of the library's w grid: no interpolation)")
      ->capture_default_str();
  app.add_option("--radius-m", radius, "cell radius")->capture_default_str();
  app.add_option("--curves", curves, "number of curves")->capture_default_str();
  app.add_option("--noise", noise, "relative force noise (Gaussian sigma)")->capture_default_str();
  app.add_option("--max-deformation", max_deformation, "deepest deformation past the true contact")
      ->capture_default_str();
  app.add_option("--step-m", step_m, "indentation step")->capture_default_str();
  app.add_option("--offset-m", offset_m, "contact offsets spread over [-offset, +offset]")
      ->capture_default_str();
  app.add_option("--pre-contact-m", pre_contact_m, "approach before the nominal contact")
      ->capture_default_str();
  app.add_option("--vertices", vertices, "library numerics: mesh vertices")->capture_default_str();
  app.add_option("--load-points", load_points, "library numerics: load points")->capture_default_str();
  app.add_option("--library-dir", library_dir, "load and save the curve library here (optional)");
  app.add_option("--seed", seed, "random seed")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  cal::CurveLibrary library;
  if (!library_dir.empty()) (void)library.load(library_dir);
  cal::CurveKey key;
  key.numerics.target_vertex_count = vertices;
  key.numerics.load_points = load_points;
  auto curve = library.curve(key, w);
  if (!curve.ok()) {
    std::fprintf(stderr, "cellflow-make-fit-data: %s\n", curve.status().to_string().c_str());
    return 1;
  }
  auto model = library.fixed_w_interpolant(key, w, max_deformation);
  if (!model.ok()) {
    std::fprintf(stderr, "cellflow-make-fit-data: %s\n", model.status().to_string().c_str());
    return 1;
  }
  if (!library_dir.empty()) (void)library.save(library_dir);
  std::filesystem::create_directories(out_dir);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double two_r = 2.0 * radius;
  char e_text[32], w_text[32];
  std::snprintf(e_text, sizeof e_text, "%g", e);
  std::snprintf(w_text, sizeof w_text, "%g", w);
  for (int c = 0; c < curves; ++c) {
    const double s = curves > 1 ? -offset_m + 2.0 * offset_m * c / (curves - 1) : 0.0;
    const std::string path =
        out_dir + "/synthetic_plates_E" + e_text + "_w" + w_text + "_" + std::to_string(c + 1) + ".csv";
    std::ofstream out(path);
    out << "# synthetic: compression between plates made by cellflow's own model (not a measurement)\n"
        << "# E = " << e << " Pa, w = " << w << ", nu = 0.48, R = " << radius
        << " m, true contact at indentation " << s << " m, relative force noise " << noise
        << " (Gaussian), library " << vertices << " vertices, " << load_points << " load points, seed "
        << seed << "\n"
        << "indentation_m,force_n\n";
    for (double x = -pre_contact_m; x <= s + max_deformation * two_r + 1e-15; x += step_m) {
      const double eps = (x - s) / two_r;
      double f = 0.0;
      if (eps > 0.0) f = e * radius * radius * model->force_scaled(w, eps) * (1.0 + noise * gauss(rng));
      char line[80];
      std::snprintf(line, sizeof line, "%.9e,%.9e\n", x, f);
      out << line;
    }
    std::printf("%s (contact %+.3g um)\n", path.c_str(), s * 1e6);
  }
  std::printf("simulations run: %d\n", library.simulations_run());
  return 0;
}
