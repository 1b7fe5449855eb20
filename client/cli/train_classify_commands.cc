#include "client/cli/train_classify_commands.h"

#include <algorithm>
#include <memory>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "client/cli/describe_command.h"
#include "core/json.h"

namespace shapeid {
namespace {

std::string FailedJson(const std::vector<FailedInput>& failed) {
  std::string out = "[";
  for (size_t i = 0; i < failed.size(); ++i) {
    if (i > 0) out += ',';
    absl::StrAppend(&out, "{\"file\":", JsonString(failed[i].path),
                    ",\"error\":", JsonString(failed[i].status.message()), "}");
  }
  return out + "]";
}

// [{"file":...,"label":...,"sample_id":N}, ...]: which sample each trained file became.
std::string TrainedJson(const std::vector<TrainedFile>& files) {
  std::string out = "[";
  for (size_t i = 0; i < files.size(); ++i) {
    if (i > 0) out += ',';
    absl::StrAppend(&out, "{\"file\":", JsonString(files[i].path),
                    ",\"label\":", JsonString(files[i].label),
                    ",\"sample_id\":", files[i].sample_id, "}");
  }
  return out + "]";
}

// Exit code of a batch: the stop reason first, then any failed file.
int BatchExitCode(const absl::Status& stopped, size_t failed, const CliContext& context,
                  absl::string_view what) {
  if (!stopped.ok()) {
    PrintCallError(context, what, stopped);
    return ExitCodeForStatus(stopped);
  }
  return failed > 0 ? kExitSomeInputsFailed : kExitOk;
}

std::string Pad(absl::string_view text, size_t width) {
  std::string out(text);
  if (out.size() < width) out.append(width - out.size(), ' ');
  return out;
}

}  // namespace

int RunTrain(const TrainOptions& options, const CliContext& context) {
  BatchOptions batch = options.batch;
  for (const std::string& pair : options.metadata) {
    const size_t equals = pair.find('=');
    if (equals == 0 || equals == std::string::npos) {
      WriteAll(context.err, absl::StrCat("shapeid: train: --metadata ", pair,
                                         ": expected KEY=VALUE with a non-empty key\n"));
      return kExitUsage;
    }
    if (!batch.metadata.emplace(pair.substr(0, equals), pair.substr(equals + 1)).second) {
      WriteAll(context.err, absl::StrCat("shapeid: train: --metadata key ", pair.substr(0, equals),
                                         " is given twice\n"));
      return kExitUsage;
    }
  }
  std::vector<LabeledFile> files;
  std::vector<std::string> unsupported;
  if (!options.label.empty()) {
    if (absl::Status format = CheckStandardInputFormat(options.paths, options.batch.read);
        !format.ok()) {
      PrintError(context.err, "train", format);
      return kExitUsage;
    }
    absl::StatusOr<std::vector<std::string>> paths = ExpandInputs(options.paths, &unsupported);
    if (!paths.ok()) {
      PrintError(context.err, "train", paths.status());
      return kExitUsage;
    }
    for (std::string& path : *paths) files.push_back({std::move(path), options.label});
  } else {
    for (const std::string& dir : options.paths) {
      absl::StatusOr<std::vector<LabeledFile>> found =
          LabeledFiles(dir, Split::kTrain, &unsupported);
      if (!found.ok()) {
        PrintError(context.err, "train",
                   absl::Status(found.status().code(),
                                absl::StrCat(found.status().message(),
                                             " (or give --label for unlabeled files)")));
        return kExitUsage;
      }
      files.insert(files.end(), found->begin(), found->end());
    }
  }
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  const bool unsupported_failed =
      ReportUnsupportedFiles(context.err, "train", unsupported, options.batch.skip_unsupported);

  TrainOutcome outcome;
  {
    Progress progress(context.err, context.progress, "train", files.size());
    outcome = TrainFiles(*client, options.gallery, files, batch, progress, context.err);
  }
  const double rate = outcome.seconds > 0 ? outcome.trained / outcome.seconds : 0;
  std::string text;
  switch (context.format) {
    case OutputFormat::kJson:
      text = absl::StrCat("{\"gallery\":", JsonString(options.gallery), ",\"files\":", files.size(),
                          ",\"trained\":", outcome.trained,
                          ",\"samples\":", TrainedJson(outcome.files),
                          ",\"failed\":", FailedJson(outcome.failed),
                          ",\"gallery_sample_count\":", outcome.gallery_sample_count,
                          ",\"seconds\":", JsonNumber(outcome.seconds),
                          ",\"stopped\":", JsonString(outcome.stopped.message()), "}\n");
      break;
    case OutputFormat::kCsv:
      text = RenderCsv(
          {{"gallery", "files", "trained", "failed", "gallery_sample_count", "seconds"},
           {{options.gallery, absl::StrCat(files.size()), absl::StrCat(outcome.trained),
             absl::StrCat(outcome.failed.size()), absl::StrCat(outcome.gallery_sample_count),
             absl::StrFormat("%.3f", outcome.seconds)}},
           {}});
      break;
    case OutputFormat::kTable:
      text = absl::StrFormat(
          "trained %d of %d files into %s in %s (%.1f files/s)%s\n", outcome.trained, files.size(),
          options.gallery, FormatSeconds(outcome.seconds), rate,
          outcome.gallery_sample_count > 0
              ? absl::StrCat("; the gallery holds ", outcome.gallery_sample_count, " samples")
              : std::string());
      if (!outcome.failed.empty()) {
        absl::StrAppend(&text, outcome.failed.size(), " files failed (listed on stderr)\n");
      }
      break;
  }
  WriteAll(context.out, text);
  std::fflush(context.out);
  return BatchExitCode(outcome.stopped, outcome.failed.size() + unsupported_failed, context,
                       absl::StrCat("train ", options.gallery));
}

std::string ClassifyJsonLine(const std::string& file, const v1::ClassifyResponse& r,
                             double seconds) {
  std::string neighbors;
  for (const v1::Neighbor& n : r.neighbors()) {
    if (!neighbors.empty()) neighbors += ',';
    // Metadata keys sorted, so that the line is the same whatever the map's order.
    std::vector<std::pair<std::string, std::string>> metadata(n.metadata().begin(),
                                                              n.metadata().end());
    std::sort(metadata.begin(), metadata.end());
    std::string fields;
    for (const auto& [key, value] : metadata) {
      absl::StrAppend(&fields, fields.empty() ? "" : ",", JsonString(key), ":", JsonString(value));
    }
    absl::StrAppend(&neighbors, "{\"sample_id\":", n.sample_id(),
                    ",\"label\":", JsonString(n.label()),
                    ",\"distance\":", JsonNumber(n.distance()),
                    ",\"source\":", JsonString(n.source()), ",\"metadata\":{", fields, "}}");
  }
  std::string votes;
  for (const v1::ClassVote& v : r.votes()) {
    if (!votes.empty()) votes += ',';
    absl::StrAppend(&votes, "{\"label\":", JsonString(v.label()),
                    ",\"weight\":", JsonNumber(v.weight()), "}");
  }
  return absl::StrCat(
      "{\"file\":", JsonString(file), ",\"label\":", JsonString(r.label()),
      ",\"unknown\":", r.unknown() ? "true" : "false",
      ",\"confidence\":", JsonNumber(r.confidence()), ",\"points\":", r.num_points(),
      ",\"neighbors\":[", neighbors, "],\"votes\":[", votes,
      "],\"describe_seconds\":", JsonNumber(DurationSeconds(r.describe_time())),
      ",\"search_seconds\":", JsonNumber(DurationSeconds(r.search_time())),
      ",\"approximate\":", r.approximate() ? "true" : "false",
      ",\"by_head\":", r.by_head() ? "true" : "false", ",\"seconds\":", JsonNumber(seconds), "}\n");
}

int RunClassify(const ClassifyOptions& options, const CliContext& context) {
  if (absl::Status format = CheckStandardInputFormat(options.paths, options.batch.read);
      !format.ok()) {
    PrintError(context.err, "classify", format);
    return kExitUsage;
  }
  std::vector<std::string> unsupported;
  absl::StatusOr<std::vector<std::string>> paths = ExpandInputs(options.paths, &unsupported);
  if (!paths.ok()) {
    PrintError(context.err, "classify", paths.status());
    return kExitUsage;
  }
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  // Up front: a missing gallery fails once, and its labels size the label column.
  absl::StatusOr<v1::Gallery> gallery = client->GetGallery(options.gallery);
  if (!gallery.ok()) {
    PrintCallError(context, absl::StrCat("classify ", options.gallery), gallery.status());
    return ExitCodeForStatus(gallery.status());
  }
  const bool unsupported_failed =
      ReportUnsupportedFiles(context.err, "classify", unsupported, options.batch.skip_unsupported);
  size_t file_width = 4, label_width = 7;  // "unknown"
  for (const std::string& path : *paths) file_width = std::max(file_width, path.size());
  for (const v1::LabelCount& lc : gallery->label_counts()) {
    label_width = std::max(label_width, lc.label().size());
  }
  const size_t top = static_cast<size_t>(std::max(options.top, 0));

  bool written = true;
  if (context.format == OutputFormat::kTable) {
    written &=
        WriteAll(context.out,
                 absl::StrCat(Pad("FILE", file_width), "  ", Pad("LABEL", label_width),
                              "  CONFIDENCE", top > 0 ? "  NEAREST (label distance)" : "", "\n"));
  } else if (context.format == OutputFormat::kCsv) {
    std::string header = "file,label,unknown,confidence,points,seconds";
    for (size_t i = 1; i <= top; ++i) {
      absl::StrAppend(&header, ",neighbor", i, "_label,neighbor", i, "_distance,neighbor", i,
                      "_source");
    }
    written &= WriteAll(context.out, header + "\r\n");
  }

  const auto on_result = [&](size_t i, const v1::ClassifyResponse& r, double seconds) {
    const std::string& file = (*paths)[i];
    std::string line;
    switch (context.format) {
      case OutputFormat::kJson:
        line = ClassifyJsonLine(file, r, seconds);
        break;
      case OutputFormat::kCsv: {
        line = absl::StrCat(CsvField(file), ",", CsvField(r.label()), ",",
                            r.unknown() ? "true" : "false", ",",
                            absl::StrFormat("%.4f", r.confidence()), ",", r.num_points(), ",",
                            absl::StrFormat("%.6f", seconds));
        for (size_t n = 0; n < top; ++n) {
          if (n < static_cast<size_t>(r.neighbors_size())) {
            absl::StrAppend(&line, ",", CsvField(r.neighbors(n).label()), ",",
                            absl::StrFormat("%.6g", r.neighbors(n).distance()), ",",
                            CsvField(r.neighbors(n).source()));
          } else {
            line += ",,,";
          }
        }
        line += "\r\n";
        break;
      }
      case OutputFormat::kTable: {
        line = absl::StrCat(Pad(file, file_width), "  ", Pad(r.label(), label_width), "  ",
                            absl::StrFormat("%9.1f%%", 100 * r.confidence()));
        for (size_t n = 0; n < top && n < static_cast<size_t>(r.neighbors_size()); ++n) {
          absl::StrAppend(&line, n == 0 ? "  " : ", ", r.neighbors(n).label(), " ",
                          absl::StrFormat("%.4g", r.neighbors(n).distance()));
        }
        line += '\n';
        break;
      }
    }
    written &= WriteAll(context.out, line);
  };
  const auto on_failure = [&](size_t i, const absl::Status& status) {
    std::fflush(context.out);  // keeps stdout and stderr in file order on a terminal
    WriteAll(context.err, FileErrorLine((*paths)[i], status));
  };

  ClassifyOutcome outcome;
  {
    Progress progress(context.err, context.progress, "classify", paths->size());
    outcome = ClassifyFiles(*client, options.gallery, options.call, *paths, options.batch, progress,
                            on_result, on_failure);
  }
  if (const int code = FinishOutput(written, context); code != kExitOk) return code;
  if (context.format == OutputFormat::kTable && context.progress != ProgressMode::kOff) {
    WriteAll(
        context.err,
        absl::StrFormat(
            "classified %d of %d files in %s (%.1f files/s)%s\n", outcome.classified, paths->size(),
            FormatSeconds(outcome.seconds),
            outcome.seconds > 0 ? outcome.classified / outcome.seconds : 0.0,
            outcome.failed.empty() ? "" : absl::StrCat(", ", outcome.failed.size(), " failed")));
  }
  return BatchExitCode(outcome.stopped, outcome.failed.size() + unsupported_failed, context,
                       absl::StrCat("classify ", options.gallery));
}

}  // namespace shapeid
