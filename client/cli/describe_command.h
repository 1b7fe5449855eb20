#ifndef SHAPEID_CLIENT_CLI_DESCRIBE_COMMAND_H_
#define SHAPEID_CLIENT_CLI_DESCRIBE_COMMAND_H_

#include <cstdio>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "client/cli/cli_common.h"
#include "core/descriptor_registry.h"
#include "core/io/read_options.h"

namespace shapeid {

// `shapeid describe`, after flag parsing.
struct DescribeOptions {
  // Compute in this process instead of asking the server: no server needed, and the same
  // code and results (the server runs the same core library).
  bool local = false;
  // With `local`: threads one large cloud's descriptor may use (CloudLimits::max_threads);
  // 0: one per core. Clouds are described one after another.
  int threads = 0;
  // Descriptor spec text; empty: the gallery's spec if `gallery` is set, else the default
  // (kDefaultDescriptorSpec). Registry defaults fill omitted parameters.
  std::string spec;
  std::string gallery;             // server mode: describe as this gallery would
  ReadOptions read;                // non-finite points, mesh sampling, an explicit format
  bool skip_unsupported = false;   // folders' other files: ignored instead of reported
  v1::SensorFrame sensor_frame;    // the sensor's frame (ParseSensorFrame); locally too
  std::vector<std::string> files;  // files, or folders walked for point-cloud files
};

// Describes every file in order, writing one record per described file to context.out (text
// line, JSON Lines record or CSV row) and one line per failed file to context.err, and carries
// on after a failed file. Checks the options and the spec (locally: before reading any file)
// first. Returns kExitOk, kExitSomeFilesFailed (also when writing the output fails),
// kExitUsage, or the server's exit code (ExitCodeForStatus) when it refuses or is unreachable.
int RunDescribe(const DescribeOptions& options, const CliContext& context);

// "<file> v0 v1 ...\n": values as %.9g, which round-trips every float.
std::string FormatTextLine(absl::string_view file, absl::Span<const float> values);

// One JSON Lines record, ending in '\n':
// {"file":...,"spec":...,"dimension":N,"descriptor":[...]}. Values as %.9g.
std::string FormatJsonLine(absl::string_view file, absl::string_view spec,
                           absl::Span<const float> values);

// "shapeid: <file>: <message>\n". Reader messages already start with the file name; it is
// not repeated.
std::string FileErrorLine(absl::string_view file, const absl::Status& status);

// The part of `shapeid describe --help` after the flags: descriptor kinds, their parameters,
// output formats, exit codes and examples.
std::string DescribeHelpFooter();

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_DESCRIBE_COMMAND_H_
