// The shapeid command-line tool: flags -> an options struct -> a command returning an exit
// code. Commands live in their own files; this file only knows CLI11.

#include <cstdio>
#include <string>

#include "CLI/CLI.hpp"
#include "client/cli/describe_command.h"

namespace {

void AddDescribe(CLI::App& app, shapeid::DescribeOptions* options, std::string* format) {
  CLI::App* describe = app.add_subcommand(
      "describe", "Compute the shape descriptor of each point-cloud file, one line per file");
  describe->add_flag("--local", options->local,
                     "Compute in this process (required until the server mode exists)");
  describe->add_option("--spec", options->spec, "Descriptor spec: KIND[:param=value,...]")
      ->capture_default_str();
  describe->add_option("--format", *format, "Output: text, or json (one JSON object per line)")
      ->check(CLI::IsMember({"text", "json"}))
      ->type_name("FORMAT")
      ->capture_default_str();
  describe->add_flag("--drop-nonfinite", options->drop_non_finite,
                     "Remove points with NaN or infinite coordinates (organised PCD clouds) "
                     "instead of failing on them");
  describe->add_option("FILE", options->files, "Point-cloud files: .pcd .ply .off .xyz .txt .csv")
      ->required()
      ->type_name("");
  describe->footer(shapeid::DescribeHelpFooter());
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("shapeid: 3D object recognition from point clouds", "shapeid");
  app.set_version_flag("--version", std::string("shapeid ") + SHAPEID_VERSION);
  app.require_subcommand(1);
  app.footer("Run 'shapeid describe --help' for the descriptor kinds, formats and examples.");
  shapeid::DescribeOptions describe;
  std::string format = "text";
  AddDescribe(app, &describe, &format);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) {
      return app.exit(e);  // --help, --version
    }
    std::fprintf(stderr, "shapeid: %s (see shapeid --help)\n", e.what());
    return shapeid::kExitUsage;
  }
  if (app.got_subcommand("describe")) {
    describe.format =
        format == "json" ? shapeid::OutputFormat::kJson : shapeid::OutputFormat::kText;
    return shapeid::RunDescribe(describe, stdout, stderr);
  }
  return shapeid::kExitUsage;
}
