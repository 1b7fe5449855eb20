#include "client/cli/describe_command.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <thread>
#include <utility>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "client/cli/input_files.h"
#include "core/descriptor.h"
#include "core/descriptor_registry.h"
#include "core/io/point_cloud_reader.h"
#include "core/json.h"
#include "core/rigid_transform.h"
#include "core/status_macros.h"

namespace shapeid {
namespace {

void AppendFloat(std::string* out, float value) {
  char buffer[32];
  const int n = std::snprintf(buffer, sizeof buffer, "%.9g", static_cast<double>(value));
  out->append(buffer, static_cast<size_t>(n));
}

}  // namespace

std::string FormatTextLine(absl::string_view file, absl::Span<const float> values) {
  std::string line(file);
  line.reserve(file.size() + 16 * values.size() + 1);
  for (float v : values) {
    line += ' ';
    AppendFloat(&line, v);
  }
  line += '\n';
  return line;
}

std::string FormatJsonLine(absl::string_view file, absl::string_view spec,
                           absl::Span<const float> values) {
  std::string line = absl::StrCat("{\"file\":", JsonString(file), ",\"spec\":", JsonString(spec),
                                  ",\"dimension\":", values.size(), ",\"descriptor\":[");
  for (size_t i = 0; i < values.size(); ++i) {
    if (i > 0) line += ',';
    // Descriptor::Compute never yields a non-finite value; should one slip through, JSON has
    // no spelling for it.
    if (std::isfinite(values[i])) {
      AppendFloat(&line, values[i]);
    } else {
      line += "null";
    }
  }
  line += "]}\n";
  return line;
}

std::string FileErrorLine(absl::string_view file, const absl::Status& status) {
  absl::string_view message = status.message();
  // The readers name standard input ("-") so.
  const absl::string_view named = file == "-" ? "standard input" : file;
  if (absl::StartsWith(message, absl::StrCat(named, ": "))) message.remove_prefix(named.size() + 2);
  return absl::StrCat("shapeid: ", named, ": ", message, "\n");
}

namespace {

std::string FormatCsvLine(absl::string_view file, absl::Span<const float> values) {
  std::string line = CsvField(file);
  for (float v : values) {
    line += ',';
    AppendFloat(&line, v);
  }
  line += "\r\n";
  return line;
}

}  // namespace

int RunDescribe(const DescribeOptions& options, const CliContext& context) {
  std::FILE* const out = context.out;
  std::FILE* const err = context.err;
  std::unique_ptr<Descriptor> local;
  RigidTransform local_frame;
  CloudLimits local_limits;
  local_limits.max_threads =
      options.threads > 0 ? options.threads
                          : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::unique_ptr<Client> client;
  std::string canonical_spec;
  if (options.local) {
    if (!options.gallery.empty()) {
      WriteAll(err, "shapeid: describe: --gallery needs the server; drop --local\n");
      return kExitUsage;
    }
    const std::string spec = options.spec.empty() ? kDefaultDescriptorSpec : options.spec;
    absl::StatusOr<std::unique_ptr<Descriptor>> descriptor = CreateDescriptor(spec);
    if (!descriptor.ok()) {
      WriteAll(err, absl::StrCat("shapeid: --spec \"", spec, "\": ", descriptor.status().message(),
                                 "\n"));
      return kExitUsage;
    }
    local = std::move(descriptor).value();
    canonical_spec = local->spec().ToString();
    // The server's rule (server/wire/proto_convert.h): the frame's up turns onto the descriptor's.
    absl::StatusOr<RigidTransform> frame =
        !options.sensor_frame.transform().empty()
            ? RigidTransformFromRows(options.sensor_frame.transform())
        : !options.sensor_frame.up().empty()
            ? RotationTakingUpTo(options.sensor_frame.up(), local->up_direction())
            : absl::StatusOr<RigidTransform>(RigidTransform());
    if (!frame.ok()) {
      PrintError(err, "describe", frame.status());
      return kExitUsage;
    }
    local_frame = *frame;
  } else {
    // The server runs the same core: a spec this build cannot parse is a usage error, said
    // once, instead of the same refusal for every file.
    if (!options.spec.empty()) {
      if (absl::StatusOr<std::unique_ptr<Descriptor>> descriptor = CreateDescriptor(options.spec);
          !descriptor.ok()) {
        WriteAll(err, absl::StrCat("shapeid: --spec \"", options.spec,
                                   "\": ", descriptor.status().message(), "\n"));
        return kExitUsage;
      }
    }
    client = ConnectOrReport(context);
    if (client == nullptr) return kExitUsage;
  }

  if (absl::Status format = CheckStandardInputFormat(options.files, options.read); !format.ok()) {
    PrintError(err, "describe", format);
    return kExitUsage;
  }
  std::vector<std::string> unsupported;
  absl::StatusOr<std::vector<std::string>> files = ExpandInputs(options.files, &unsupported);
  if (!files.ok()) {
    PrintError(err, "describe", files.status());
    return kExitUsage;
  }
  bool failed = ReportUnsupportedFiles(err, "describe", unsupported, options.skip_unsupported);
  bool header_written = false;
  std::vector<float> values;
  std::string line;
  Progress progress(err, context.progress, "describe", files->size());
  for (const std::string& file : *files) {
    absl::Status status;
    absl::StatusOr<ReadResult> read = ReadInputCloud(file, options.read);
    if (!read.ok()) {
      status = read.status();
    } else if (local != nullptr) {
      if (!local_frame.is_identity()) {
        ApplyRigidTransform(local_frame, read->cloud.mutable_xyz().data(), read->cloud.size());
      }
      status = local->Compute(read->cloud, &values, local_limits);
    } else {
      Client::DescribeOptions call;
      call.spec = options.spec;
      call.gallery = options.gallery;
      call.sensor_frame = options.sensor_frame;
      absl::StatusOr<v1::DescribeResponse> response = client->Describe(read->cloud, call);
      if (!response.ok() && StopsBatch(response.status())) {
        progress.Finish();
        std::fflush(out);
        PrintCallError(context, "describe", response.status());
        return ExitCodeForStatus(response.status());
      }
      status = response.status();
      if (response.ok()) {
        values.assign(response->values().begin(), response->values().end());
        canonical_spec = response->descriptor_spec();
      }
    }
    if (!status.ok()) {
      failed = true;
      std::fflush(out);  // keeps the two streams in file order on a terminal
      line = FileErrorLine(file, status);
      progress.Interrupt([&] { WriteAll(err, line); });
      progress.Advance(1, 1);
      continue;
    }
    switch (context.format) {
      case OutputFormat::kJson:
        line = FormatJsonLine(file, canonical_spec, values);
        break;
      case OutputFormat::kCsv:
        line.clear();
        if (!header_written) {
          line = "file";
          for (size_t i = 0; i < values.size(); ++i) absl::StrAppend(&line, ",d", i);
          line += "\r\n";
          header_written = true;
        }
        line += FormatCsvLine(file, values);
        break;
      case OutputFormat::kTable:
        line = FormatTextLine(file, values);
        break;
    }
    progress.Interrupt([&] { std::fwrite(line.data(), 1, line.size(), out); });
    progress.Advance(1, 0);
  }
  progress.Finish();
  if (std::fflush(out) != 0 || std::ferror(out)) {
    WriteAll(err, "shapeid: cannot write the output\n");
    return kExitSomeFilesFailed;
  }
  return failed ? kExitSomeFilesFailed : kExitOk;
}

std::string DescribeHelpFooter() {
  return absl::StrCat(
      "Descriptor kinds (--spec KIND or KIND:param=value,...; omitted parameters take the\n"
      "defaults shown):\n",
      DescribeRegistry(),
      "\n"
      "Files: .pcd (PCD v0.7: ascii, binary, binary_compressed), .ply (ascii, binary little or\n"
      "big endian), .off, .obj, .stl, .vtk (legacy polydata), .las (1.0-1.4), .npy / .npz\n"
      "(N x 3 or more columns, or x/y/z fields), .xyz / .txt / .xyzn / .xyzrgb / .pts (x y z\n"
      "first on each line, blank- or comma-separated), .csv (comma or semicolon); any of them\n"
      "gzipped (.gz). Meshes (files with faces) are sampled to --mesh-points points (2,048),\n"
      "area-weighted and seeded. FILE - reads standard input (with --input-format). Folders\n"
      "are walked for these files; their other files are listed and make the exit status 1\n"
      "unless --skip-unsupported.\n"
      "Coordinates are recentered on the bounding box before conversion to float; every\n"
      "descriptor is translation invariant.\n"
      "\n"
      "Without --local the server computes the descriptor (--spec, or --gallery for a gallery's\n"
      "spec); with --local this process does, with the same code.\n"
      "\n"
      "Output: table prints one line per file, the file name and then the values (%.9g, which\n"
      "round-trips float); csv a header then one row per file; json one JSON object per line:\n"
      "  {\"file\":...,\"spec\":<canonical spec>,\"dimension\":N,\"descriptor\":[...]}\n"
      "\n"
      "Exit status: 0 every file described; 1 some file failed (one line each on stderr, the\n"
      "others are still described); 2 usage error or bad --spec (no file is read); 3 server\n"
      "unreachable; 4 the server refused the request.\n"
      "\n"
      "Examples:\n"
      "  shapeid describe --local chair.pcd\n"
      "  shapeid describe --local --spec rphsd:refs=cross7,bins=10 a.pcd b.xyz\n"
      "  shapeid describe --local --spec comsd:grid=50 --format json models/*.pcd > d.jsonl\n"
      "  shapeid describe --local --drop-nonfinite --spec 'rphsd:refs=[0,0,0;1,0,0;0,1,0]' "
      "kinect.pcd\n");
}

}  // namespace shapeid
