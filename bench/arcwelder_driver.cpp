// A console front end for FormerLurker's ArcWelder library (the `arc_welder` class of
// ArcWelderLib / the OctoPrint ArcWelderPlugin), standing in for ArcWelderConsole where
// its TCLAP headers are not at hand. It is zwplan's own code: it only parses the
// command line and calls the library the way ArcWelderConsole.cpp does, with the same
// defaults; the library sources are NOT part of this repository (AGPL-3.0), see
// bench/README.md "Building ArcWelder".
//
//   arcwelder_driver SOURCE TARGET [--resolution-mm=X] [--path-tolerance-percent=P]
//       [--max-radius-mm=R] [--default-xyz-precision=N] [--default-e-precision=N]
//       [--extrusion-rate-variance-percent=V] [--allow-dynamic-precision] [--version]
//
// Options take the console's long names and value ranges (path tolerance a fraction in
// (0, 1), xyz / e precision 3..6); anything else is refused, as the console would.
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>

#include "arc_welder.h"
#include "logger.h"
#include "version.h"

namespace {

bool on_progress_quiet(arc_welder_progress, logger*, int) { return true; }

// "--name=value" -> value if the argument has that name.
bool value_of(const std::string& arg, const std::string& name, std::string& value) {
  const std::string prefix = "--" + name + "=";
  if (arg.compare(0, prefix.size(), prefix) != 0) return false;
  value = arg.substr(prefix.size());
  return true;
}

int usage(const std::string& why) {
  std::cerr << "arcwelder_driver: " << why << "\n"
            << "usage: arcwelder_driver SOURCE TARGET [--resolution-mm=X]"
               " [--path-tolerance-percent=P] [--max-radius-mm=R]"
               " [--default-xyz-precision=N] [--default-e-precision=N]"
               " [--extrusion-rate-variance-percent=V] [--allow-dynamic-precision]\n";
  return 1;
}

}  // namespace

int main(int argc, char* argv[]) {
  arc_welder_args args;  // the library's defaults, which are the console's
  std::string value;
  int positional = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--version") {
      std::cout << "ArcWelder library " << GIT_TAGGED_VERSION << " (" << GIT_COMMIT_HASH
                << ", " << BUILD_DATE << ")\n";
      return 0;
    } else if (arg == "--allow-dynamic-precision") {
      args.allow_dynamic_precision = true;
    } else if (value_of(arg, "resolution-mm", value)) {
      args.resolution_mm = std::atof(value.c_str());
    } else if (value_of(arg, "path-tolerance-percent", value)) {
      args.path_tolerance_percent = std::atof(value.c_str());
    } else if (value_of(arg, "max-radius-mm", value)) {
      args.max_radius_mm = std::atof(value.c_str());
    } else if (value_of(arg, "default-xyz-precision", value)) {
      args.default_xyz_precision = static_cast<unsigned char>(std::atoi(value.c_str()));
    } else if (value_of(arg, "default-e-precision", value)) {
      args.default_e_precision = static_cast<unsigned char>(std::atoi(value.c_str()));
    } else if (value_of(arg, "extrusion-rate-variance-percent", value)) {
      args.extrusion_rate_variance_percent = std::atof(value.c_str());
    } else if (arg.compare(0, 1, "-") == 0) {
      return usage("unknown option " + arg);
    } else if (positional == 0) {
      args.source_path = arg;
      ++positional;
    } else if (positional == 1) {
      args.target_path = arg;
      ++positional;
    } else {
      return usage("too many arguments");
    }
  }
  if (positional == 0) return usage("no source file");
  if (positional == 1) args.target_path = args.source_path;  // the console overwrites
  // the console's checks (ArcWelderConsole.cpp), with its messages' meaning
  if (!utilities::does_file_exist(args.source_path)) return usage("no such source file");
  if (args.resolution_mm <= 0) return usage("--resolution-mm must be > 0");
  if (args.path_tolerance_percent <= 0 || args.path_tolerance_percent >= 1.0)
    return usage("--path-tolerance-percent must be in (0, 1) (a fraction: 0.05 = 5%)");
  if (args.max_radius_mm <= 0) return usage("--max-radius-mm must be > 0");
  if (args.default_xyz_precision < 3 || args.default_xyz_precision > 6)
    return usage("--default-xyz-precision must be 3..6");
  if (args.default_e_precision < 3 || args.default_e_precision > 6)
    return usage("--default-e-precision must be 3..6");
  if (args.extrusion_rate_variance_percent < 0)
    return usage("--extrusion-rate-variance-percent must be >= 0");

  // the console's logger: one ArcWelder logger, here at WARNING so a run prints nothing
  std::vector<std::string> names(1, ARC_WELDER_LOGGER_NAME);
  std::vector<int> levels(1, static_cast<int>(log_levels::DEBUG));
  logger log(names, levels);
  log.set_log_level_by_value(log_level_values[log_levels::WARNING]);
  args.log = &log;
  args.callback = on_progress_quiet;
  args.box_encoding = utilities::box_drawing::ASCII;

  arc_welder welder(args);
  const arc_welder_results results = welder.process();
  if (!results.success) {
    std::cerr << "arcwelder_driver: processing failed: " << results.message << "\n";
    return 2;
  }
  std::cout << "arcs_created=" << results.progress.arcs_created
            << " points_compressed=" << results.progress.points_compressed << "\n";
  return 0;
}
