#ifndef SHAPEID_CLIENT_CLI_DESCRIBE_COMMAND_H_
#define SHAPEID_CLIENT_CLI_DESCRIBE_COMMAND_H_

#include <cstdio>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "core/descriptor_registry.h"

namespace shapeid {

// Exit codes of the shapeid tool.
inline constexpr int kExitOk = 0;
inline constexpr int kExitSomeFilesFailed = 1;  // the other files were still described
inline constexpr int kExitUsage = 2;            // bad flags or spec; no file was read

enum class OutputFormat { kText, kJson };

// `shapeid describe`, after flag parsing.
struct DescribeOptions {
  // Compute in this process. Default false, because the default will be to ask the shapeid
  // server (which holds the galleries); until the gRPC service exists, false is an error.
  bool local = false;
  std::string spec = kDefaultDescriptorSpec;  // descriptor spec text; registry defaults fill the rest
  OutputFormat format = OutputFormat::kText;
  bool drop_non_finite = false;  // ReadOptions::drop_non_finite
  std::vector<std::string> files;
};

// Describes every file in order, writing one line per described file to `out` and one line
// per failed file to `err`, and carries on after a failed file. Checks the options and the
// spec before reading any file. Returns kExitOk, kExitSomeFilesFailed (also when writing
// `out` fails) or kExitUsage.
int RunDescribe(const DescribeOptions& options, std::FILE* out, std::FILE* err);

// "<file> v0 v1 ...\n": values as %.9g, which round-trips every float.
std::string FormatTextLine(absl::string_view file, absl::Span<const float> values);

// One JSON Lines record, ending in '\n':
// {"file":...,"spec":...,"dimension":N,"descriptor":[...]}. Values as %.9g.
std::string FormatJsonLine(absl::string_view file, absl::string_view spec,
                           absl::Span<const float> values);

// `text` as a quoted JSON string. Control characters are escaped; a byte that is not part of
// valid UTF-8 (file names are bytes) becomes U+FFFD so that the output stays valid JSON.
std::string JsonString(absl::string_view text);

// "shapeid: <file>: <message>\n". Reader messages already start with the file name; it is
// not repeated.
std::string FileErrorLine(absl::string_view file, const absl::Status& status);

// The part of `shapeid describe --help` after the flags: descriptor kinds, their parameters,
// output formats, exit codes and examples.
std::string DescribeHelpFooter();

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_DESCRIBE_COMMAND_H_
