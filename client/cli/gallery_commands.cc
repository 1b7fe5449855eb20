#include "client/cli/gallery_commands.h"

#include <algorithm>
#include <cstdint>
#include <ctime>
#include <memory>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "client/gallery_file.h"
#include "core/json.h"

namespace shapeid {
namespace {

std::string Timestamp(const google::protobuf::Timestamp& t) {
  if (t.seconds() == 0 && t.nanos() == 0) return "";
  const std::time_t seconds = static_cast<std::time_t>(t.seconds());
  std::tm utc;
  gmtime_r(&seconds, &utc);
  char buffer[32];
  std::strftime(buffer, sizeof buffer, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return buffer;
}

std::string Number(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.9g", value);
  return buffer;
}

// Prints a table or CSV (table formats only; json callers print their own lines).
bool PrintRows(const Table& table, const CliContext& context) {
  return WriteAll(context.out,
                  context.format == OutputFormat::kCsv ? RenderCsv(table) : RenderTable(table));
}

// ,"head":{...} when the server has fitted the gallery a head, else nothing.
std::string HeadJson(const v1::Gallery& g) {
  if (!g.has_head()) return "";
  const v1::GalleryHead& h = g.head();
  return absl::StrCat(
      ",\"head\":{\"fitted_version\":", h.fitted_version(),
      ",\"answers\":", h.answers() ? "true" : "false", ",\"fitted_samples\":", h.fitted_samples(),
      ",\"fitted_vectors\":", h.fitted_vectors(), ",\"holdout_samples\":", h.holdout_samples(),
      ",\"holdout_vectors\":", h.holdout_vectors(),
      ",\"holdout_accuracy\":", JsonNumber(h.holdout_accuracy()),
      ",\"fit_seconds\":", JsonNumber(h.fit_time().seconds() + 1e-9 * h.fit_time().nanos()), "}");
}

// The `learned` line of `gallery show`.
std::string HeadLine(const v1::Gallery& g) {
  if (!g.has_head()) return "not yet (kNN vote alone)";
  const v1::GalleryHead& h = g.head();
  std::string state = h.answers() ? "answers with the vote" : "idle: labels changed since";
  if (h.answers() && h.fitted_version() != g.version()) state += "; refit pending";
  return absl::StrCat(
      "head fitted on version ", h.fitted_version(), " (", h.fitted_samples(), " samples, ",
      h.fitted_vectors(), " vectors) in ",
      absl::StrFormat("%.1f s; %.1f %%", h.fit_time().seconds() + 1e-9 * h.fit_time().nanos(),
                      100 * h.holdout_accuracy()),
      " on ", h.holdout_vectors(), " held-out vectors; ", state);
}

std::vector<std::string> GalleryRow(const v1::Gallery& g) {
  return {g.name(),
          g.descriptor_spec(),
          absl::StrCat(g.dimension()),
          absl::StrCat(g.knn().k()),
          WeightingName(g.knn().weighting()),
          ScalingName(g.knn().scaling()),
          absl::StrCat(g.sample_count()),
          absl::StrCat(g.label_counts_size()),
          Timestamp(g.update_time())};
}

const std::vector<std::string> kGalleryHeader = {
    "NAME", "SPEC", "DIM", "K", "WEIGHTING", "SCALING", "SAMPLES", "LABELS", "UPDATED"};
const std::vector<bool> kGalleryRightAligned = {false, false, true, true, false,
                                                false, true,  true, false};

// The gallery as `gallery show` prints it: a summary and its labels (table), one JSON
// object, or the label counts (csv).
int PrintGallery(const v1::Gallery& g, const CliContext& context) {
  if (context.format == OutputFormat::kJson)
    return FinishOutput(WriteAll(context.out, GalleryJson(g)), context);
  if (context.format == OutputFormat::kCsv) {
    Table table{{"label", "count"}, {}, {}};
    for (const v1::LabelCount& lc : g.label_counts()) {
      table.rows.push_back({lc.label(), absl::StrCat(lc.count())});
    }
    return FinishOutput(PrintRows(table, context), context);
  }
  std::string text = absl::StrCat(
      "gallery     ", g.name(), "\n", "descriptor  ", g.descriptor_spec(), " (", g.dimension(),
      " values)\n", "knn         k=", g.knn().k(), ", ", WeightingName(g.knn().weighting()),
      " votes, ", ScalingName(g.knn().scaling()), " scaling\n", "reject      ",
      g.reject_distance() > 0 ? absl::StrCat("beyond distance ", Number(g.reject_distance()))
                              : std::string("never (always a label)"),
      "\n", "augment     ",
      g.augmentation().views() > 0
          ? absl::StrCat(g.augmentation().views(), " views per cloud (noise ",
                         Number(g.augmentation().noise()), ", ", g.augmentation().min_points(), "-",
                         g.augmentation().max_points(), " points, ",
                         g.augmentation().random_pose() ? "random" : "fixed", " pose",
                         g.augmentation().mix() == v1::VIEW_MIX_VARIED ? ", varied views" : "", ")")
          : std::string("off"),
      "\n", "samples     ", g.sample_count(), " in ", g.label_counts_size(), " labels (",
      g.vector_count(), " descriptors)\n", "learned     ", HeadLine(g), "\n", "search      ",
      g.approximate_lists() > 0
          ? absl::StrCat("approximate, ", g.approximate_lists(),
                         " cells (classify --exact searches every descriptor)")
          : std::string("exact"),
      "\n", "version     ", g.version(), "\n", "created     ", Timestamp(g.create_time()), "\n",
      "updated     ", Timestamp(g.update_time()), "\n", "made by     descriptor version ",
      g.descriptor_version(), ", shapeid ", g.software_version(), "\n",
      g.incompatible().empty() ? std::string()
                               : absl::StrCat("UNUSABLE    ", g.incompatible(), "\n"));
  if (g.label_counts_size() > 0) {
    Table table{{"LABEL", "SAMPLES"}, {}, {false, true}};
    for (const v1::LabelCount& lc : g.label_counts()) {
      table.rows.push_back({lc.label(), absl::StrCat(lc.count())});
    }
    absl::StrAppend(&text, "\n", RenderTable(table));
  }
  return FinishOutput(WriteAll(context.out, text), context);
}

}  // namespace

std::string ScalingName(v1::FeatureScaling scaling) {
  switch (scaling) {
    case v1::FEATURE_SCALING_ZSCORE:
      return "zscore";
    case v1::FEATURE_SCALING_MAXABS:
      return "maxabs";
    default:
      return "none";
  }
}

std::string WeightingName(v1::VoteWeighting weighting) {
  return weighting == v1::VOTE_WEIGHTING_DISTANCE ? "distance" : "uniform";
}

std::string GalleryJson(const v1::Gallery& g) {
  std::string labels;
  for (const v1::LabelCount& lc : g.label_counts()) {
    if (!labels.empty()) labels += ',';
    absl::StrAppend(&labels, "{\"label\":", JsonString(lc.label()), ",\"count\":", lc.count(), "}");
  }
  return absl::StrCat(
      "{\"name\":", JsonString(g.name()), ",\"descriptor_spec\":", JsonString(g.descriptor_spec()),
      ",\"dimension\":", g.dimension(), ",\"k\":", g.knn().k(),
      ",\"weighting\":", JsonString(WeightingName(g.knn().weighting())),
      ",\"scaling\":", JsonString(ScalingName(g.knn().scaling())),
      ",\"reject_distance\":", JsonNumber(g.reject_distance()),
      ",\"sample_count\":", g.sample_count(), ",\"vector_count\":", g.vector_count(),
      ",\"approximate_lists\":", g.approximate_lists(),
      ",\"augment_views\":", g.augmentation().views(),
      ",\"augment_random_pose\":", g.augmentation().random_pose() ? "true" : "false",
      ",\"augment_mix\":\"", g.augmentation().mix() == v1::VIEW_MIX_VARIED ? "varied" : "camera",
      "\"", HeadJson(g), ",\"label_counts\":[", labels, "]",
      ",\"create_time\":", JsonString(Timestamp(g.create_time())),
      ",\"update_time\":", JsonString(Timestamp(g.update_time())), ",\"version\":", g.version(),
      ",\"descriptor_version\":", g.descriptor_version(),
      ",\"software_version\":", JsonString(g.software_version()),
      g.incompatible().empty() ? std::string()
                               : absl::StrCat(",\"incompatible\":", JsonString(g.incompatible())),
      "}\n");
}

absl::StatusOr<v1::CreateGalleryRequest> CreateGalleryRequestFor(
    const GalleryCreateOptions& options) {
  v1::CreateGalleryRequest request;
  request.set_name(options.name);
  request.set_descriptor_spec(options.spec);
  request.mutable_knn()->set_k(options.k);
  if (options.weighting == "uniform") {
    request.mutable_knn()->set_weighting(v1::VOTE_WEIGHTING_UNIFORM);
  } else if (options.weighting == "distance") {
    request.mutable_knn()->set_weighting(v1::VOTE_WEIGHTING_DISTANCE);
  } else if (!options.weighting.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("--weighting \"", options.weighting, "\": use uniform or distance"));
  }
  if (options.scaling == "none") {
    request.mutable_knn()->set_scaling(v1::FEATURE_SCALING_NONE);
  } else if (options.scaling == "zscore") {
    request.mutable_knn()->set_scaling(v1::FEATURE_SCALING_ZSCORE);
  } else if (options.scaling == "maxabs") {
    request.mutable_knn()->set_scaling(v1::FEATURE_SCALING_MAXABS);
  } else if (!options.scaling.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("--scaling \"", options.scaling, "\": use none, zscore or maxabs"));
  }
  request.set_reject_distance(options.reject_distance);
  if (options.augment_views > 0 || options.augment_random_pose || !options.augment_mix.empty()) {
    request.mutable_augmentation()->set_views(options.augment_views);
    request.mutable_augmentation()->set_random_pose(options.augment_random_pose);
    if (options.augment_mix == "varied") {
      request.mutable_augmentation()->set_mix(v1::VIEW_MIX_VARIED);
    } else if (options.augment_mix == "camera") {
      request.mutable_augmentation()->set_mix(v1::VIEW_MIX_CAMERA);
    } else if (!options.augment_mix.empty()) {
      return absl::InvalidArgumentError(
          absl::StrCat("--augment-mix \"", options.augment_mix, "\": use camera or varied"));
    }
  }
  return request;
}

int RunGalleryCreate(const GalleryCreateOptions& options, const CliContext& context) {
  absl::StatusOr<v1::CreateGalleryRequest> request = CreateGalleryRequestFor(options);
  if (!request.ok()) {
    PrintError(context.err, "", request.status());
    return kExitUsage;
  }
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  absl::StatusOr<v1::Gallery> gallery = client->CreateGallery(*request);
  if (!gallery.ok() && options.exist_ok && absl::IsAlreadyExists(gallery.status())) {
    gallery = client->GetGallery(options.name);
  }
  if (!gallery.ok()) {
    PrintCallError(context, absl::StrCat("gallery create ", options.name), gallery.status());
    return ExitCodeForStatus(gallery.status());
  }
  if (context.format == OutputFormat::kJson)
    return FinishOutput(WriteAll(context.out, GalleryJson(*gallery)), context);
  Table table{kGalleryHeader, {GalleryRow(*gallery)}, kGalleryRightAligned};
  return FinishOutput(PrintRows(table, context), context);
}

int RunGalleryList(const CliContext& context) {
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  absl::StatusOr<std::vector<v1::Gallery>> galleries = client->ListGalleries();
  if (!galleries.ok()) {
    PrintCallError(context, "gallery list", galleries.status());
    return ExitCodeForStatus(galleries.status());
  }
  if (context.format == OutputFormat::kJson) {
    bool written = true;
    for (const v1::Gallery& g : *galleries) written &= WriteAll(context.out, GalleryJson(g));
    return FinishOutput(written, context);
  }
  Table table{kGalleryHeader, {}, kGalleryRightAligned};
  for (const v1::Gallery& g : *galleries) table.rows.push_back(GalleryRow(g));
  return FinishOutput(PrintRows(table, context), context);
}

int RunGalleryShow(const std::string& name, const CliContext& context) {
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  absl::StatusOr<v1::Gallery> gallery = client->GetGallery(name);
  if (!gallery.ok()) {
    PrintCallError(context, absl::StrCat("gallery show ", name), gallery.status());
    return ExitCodeForStatus(gallery.status());
  }
  return PrintGallery(*gallery, context);
}

int RunGalleryDelete(const std::string& name, bool missing_ok, const CliContext& context) {
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  absl::StatusOr<uint64_t> deleted = client->DeleteGallery(name);
  if (!deleted.ok() && missing_ok && absl::IsNotFound(deleted.status())) deleted = 0;
  if (!deleted.ok()) {
    PrintCallError(context, absl::StrCat("gallery delete ", name), deleted.status());
    return ExitCodeForStatus(deleted.status());
  }
  std::string text;
  switch (context.format) {
    case OutputFormat::kJson:
      text = absl::StrCat("{\"name\":", JsonString(name), ",\"samples_deleted\":", *deleted, "}\n");
      break;
    case OutputFormat::kCsv:
      text = RenderCsv({{"name", "samples_deleted"}, {{name, absl::StrCat(*deleted)}}, {}});
      break;
    case OutputFormat::kTable:
      text = absl::StrCat("deleted gallery ", name, " (", *deleted, " samples)\n");
      break;
  }
  return FinishOutput(WriteAll(context.out, text), context);
}

int RunGalleryRemove(const GalleryRemoveOptions& options, const CliContext& context) {
  if (options.sample_ids.empty() && options.labels.empty()) {
    WriteAll(context.err, "shapeid: gallery remove: give --label and/or --id (what to remove)\n");
    return kExitUsage;
  }
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  absl::StatusOr<v1::RemoveSamplesResponse> removed =
      client->RemoveSamples(options.name, options.sample_ids, options.labels);
  if (!removed.ok()) {
    PrintCallError(context, absl::StrCat("gallery remove ", options.name), removed.status());
    return ExitCodeForStatus(removed.status());
  }
  std::string text;
  switch (context.format) {
    case OutputFormat::kJson:
      text =
          absl::StrCat("{\"name\":", JsonString(options.name), ",\"removed\":", removed->removed(),
                       ",\"remaining\":", removed->remaining(), "}\n");
      break;
    case OutputFormat::kCsv:
      text = RenderCsv(
          {{"name", "removed", "remaining"},
           {{options.name, absl::StrCat(removed->removed()), absl::StrCat(removed->remaining())}},
           {}});
      break;
    case OutputFormat::kTable:
      text = absl::StrCat("removed ", removed->removed(), " samples from ", options.name, " (",
                          removed->remaining(), " remain)\n");
      break;
  }
  return FinishOutput(WriteAll(context.out, text), context);
}

namespace {

// A sample's metadata, keys sorted: as a JSON object, and as "k=v, k=v" for the table.
std::vector<std::pair<std::string, std::string>> SortedMetadata(const v1::SampleInfo& sample) {
  std::vector<std::pair<std::string, std::string>> metadata(sample.metadata().begin(),
                                                            sample.metadata().end());
  std::sort(metadata.begin(), metadata.end());
  return metadata;
}

std::string MetadataJson(const v1::SampleInfo& sample) {
  std::string out = "{";
  for (const auto& [key, value] : SortedMetadata(sample)) {
    absl::StrAppend(&out, out.size() > 1 ? "," : "", JsonString(key), ":", JsonString(value));
  }
  return out + "}";
}

std::string SampleLine(const v1::SampleInfo& sample, OutputFormat format) {
  switch (format) {
    case OutputFormat::kJson:
      return absl::StrCat("{\"sample_id\":", sample.sample_id(),
                          ",\"label\":", JsonString(sample.label()), ",\"views\":", sample.views(),
                          ",\"source\":", JsonString(sample.source()),
                          ",\"metadata\":", MetadataJson(sample), "}\n");
    case OutputFormat::kCsv:
      return absl::StrCat(sample.sample_id(), ",", CsvField(sample.label()), ",", sample.views(),
                          ",", CsvField(sample.source()), ",", CsvField(MetadataJson(sample)),
                          "\r\n");
    case OutputFormat::kTable: {
      std::vector<std::string> pairs;
      for (const auto& [key, value] : SortedMetadata(sample)) {
        pairs.push_back(absl::StrCat(key, "=", value));
      }
      return absl::StrFormat("%-20d  %-16s  %5d  %s%s\n", sample.sample_id(), sample.label(),
                             sample.views(), sample.source().empty() ? "-" : sample.source(),
                             pairs.empty() ? "" : absl::StrCat("  ", absl::StrJoin(pairs, ", ")));
    }
  }
  return "";
}

}  // namespace

int RunGallerySamples(const GallerySamplesOptions& options, const CliContext& context) {
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  v1::ListSamplesRequest request;
  request.set_gallery(options.name);
  request.set_label(options.label);
  bool written = true;
  if (context.format == OutputFormat::kTable) {
    written &= WriteAll(context.out, absl::StrFormat("%-20s  %-16s  %5s  %s\n", "ID", "LABEL",
                                                     "VIEWS", "SOURCE  METADATA"));
  } else if (context.format == OutputFormat::kCsv) {
    written &= WriteAll(context.out, "sample_id,label,views,source,metadata\r\n");
  }
  uint64_t listed = 0;
  while (written) {
    const uint64_t left = options.limit == 0 ? UINT64_MAX : options.limit - listed;
    request.set_page_size(static_cast<uint32_t>(std::min<uint64_t>(options.page_size, left)));
    absl::StatusOr<v1::ListSamplesResponse> page = client->ListSamples(request);
    if (!page.ok()) {
      std::fflush(context.out);
      PrintCallError(context, absl::StrCat("gallery samples ", options.name), page.status());
      return ExitCodeForStatus(page.status());
    }
    for (const v1::SampleInfo& sample : page->samples()) {
      written &= WriteAll(context.out, SampleLine(sample, context.format));
    }
    listed += static_cast<uint64_t>(page->samples_size());
    if (page->next_page_token().empty() || (options.limit > 0 && listed >= options.limit)) break;
    request.set_page_token(page->next_page_token());
  }
  return FinishOutput(written, context);
}

int RunGalleryExport(const std::string& name, const std::string& file, const CliContext& context) {
  const std::string what = absl::StrCat("gallery export ", name);
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  absl::StatusOr<std::unique_ptr<GalleryFileWriter>> writer = GalleryFileWriter::Open(file);
  if (!writer.ok()) {
    PrintError(context.err, what, writer.status());
    return kExitUsage;
  }
  uint64_t samples = 0;
  absl::Status file_error;
  absl::Status status = client->ExportGallery(name, [&](const v1::GalleryExportChunk& chunk) {
    if (chunk.has_samples()) samples += static_cast<uint64_t>(chunk.samples().sample_ids_size());
    file_error = (*writer)->Write(chunk);
    return file_error;
  });
  if (status.ok()) status = file_error = (*writer)->Commit();
  if (!file_error.ok()) {  // the server was fine; the file was not
    PrintError(context.err, what, file_error);
    return kExitSomeInputsFailed;
  }
  if (!status.ok()) {  // `file` is left as it was
    PrintCallError(context, what, status);
    return ExitCodeForStatus(status);
  }
  // The summary must not mix with an export written to stdout.
  std::FILE* out = file == "-" ? context.err : context.out;
  const std::string shown = file == "-" ? "stdout" : file;
  const uint64_t bytes = (*writer)->bytes_written();
  switch (context.format) {
    case OutputFormat::kJson:
      return FinishOutput(WriteAll(out, absl::StrCat("{\"name\":", JsonString(name), ",\"file\":",
                                                     JsonString(shown), ",\"samples\":", samples,
                                                     ",\"bytes\":", bytes, "}\n")),
                          context);
    case OutputFormat::kCsv:
      return FinishOutput(
          WriteAll(out, RenderCsv({{"name", "file", "samples", "bytes"},
                                   {{name, shown, absl::StrCat(samples), absl::StrCat(bytes)}},
                                   {}})),
          context);
    case OutputFormat::kTable:
      break;
  }
  if (context.progress != ProgressMode::kOff) {
    WriteAll(context.err, absl::StrCat("exported gallery '", name, "': ", samples, " samples to ",
                                       shown, " (", bytes, " bytes)\n"));
  }
  return kExitOk;
}

int RunGalleryImport(const std::string& file, const std::string& new_name,
                     const CliContext& context) {
  // Errors of the file name it; the server's do not.
  absl::StatusOr<std::unique_ptr<GalleryFileReader>> reader = GalleryFileReader::Open(file);
  if (!reader.ok()) {
    PrintError(context.err, "gallery import", reader.status());
    return kExitUsage;
  }
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  bool read_failed = false;
  absl::StatusOr<v1::Gallery> gallery = client->ImportGallery(
      [&](v1::GalleryExportChunk* chunk) {
        absl::StatusOr<bool> more = (*reader)->Next(chunk);
        read_failed = !more.ok();
        return more;
      },
      new_name);
  if (!gallery.ok()) {
    // A damaged file (DATA_LOSS, from the reader or the server) is a refusal too: exit 4.
    PrintCallError(context, read_failed ? "gallery import" : absl::StrCat("gallery import ", file),
                   gallery.status());
    return ExitCodeForStatus(gallery.status());
  }
  return PrintGallery(*gallery, context);
}

int RunDescriptors(const CliContext& context) {
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  absl::StatusOr<std::vector<v1::DescriptorKind>> kinds = client->ListDescriptors();
  if (!kinds.ok()) {
    PrintCallError(context, "descriptors", kinds.status());
    return ExitCodeForStatus(kinds.status());
  }
  if (context.format == OutputFormat::kJson) {
    bool written = true;
    for (const v1::DescriptorKind& kind : *kinds) {
      std::string parameters;
      for (const v1::DescriptorParameter& p : kind.parameters()) {
        if (!parameters.empty()) parameters += ',';
        absl::StrAppend(&parameters, "{\"name\":", JsonString(p.name()),
                        ",\"default\":", JsonString(p.default_value()),
                        ",\"help\":", JsonString(p.help()), "}");
      }
      written &=
          WriteAll(context.out, absl::StrCat("{\"kind\":", JsonString(kind.kind()),
                                             ",\"summary\":", JsonString(kind.summary()),
                                             ",\"default_spec\":", JsonString(kind.default_spec()),
                                             ",\"default_dimension\":", kind.default_dimension(),
                                             ",\"parameters\":[", parameters, "]}\n"));
    }
    return FinishOutput(written, context);
  }
  if (context.format == OutputFormat::kCsv) {
    Table table{{"kind", "parameter", "default", "help"}, {}, {}};
    for (const v1::DescriptorKind& kind : *kinds) {
      for (const v1::DescriptorParameter& p : kind.parameters()) {
        table.rows.push_back({kind.kind(), p.name(), p.default_value(), p.help()});
      }
    }
    return FinishOutput(PrintRows(table, context), context);
  }
  std::string text;
  for (const v1::DescriptorKind& kind : *kinds) {
    absl::StrAppend(&text, kind.kind(), ": ", kind.summary(), "\n  default ", kind.default_spec(),
                    " (", kind.default_dimension(), " values)\n");
    Table table{{"  PARAMETER", "DEFAULT", "MEANING"}, {}, {}};
    for (const v1::DescriptorParameter& p : kind.parameters()) {
      table.rows.push_back({absl::StrCat("  ", p.name()), p.default_value(), p.help()});
    }
    absl::StrAppend(&text, RenderTable(table), "\n");
  }
  return FinishOutput(WriteAll(context.out, text), context);
}

int RunHealth(const CliContext& context) {
  std::unique_ptr<Client> client = ConnectOrReport(context);
  if (client == nullptr) return kExitUsage;
  const absl::Status health = client->CheckHealth();
  const std::string status = health.ok() ? "SERVING" : "NOT_SERVING";
  std::string text;
  switch (context.format) {
    case OutputFormat::kJson:
      text = absl::StrCat(
          "{\"status\":", JsonString(status), ",\"target\":", JsonString(context.client.target),
          health.ok() ? "" : absl::StrCat(",\"error\":", JsonString(health.message())), "}\n");
      break;
    case OutputFormat::kCsv:
      text = RenderCsv({{"status", "target", "error"},
                        {{status, context.client.target, std::string(health.message())}},
                        {}});
      break;
    case OutputFormat::kTable:
      text = absl::StrCat(status, " ", context.client.target,
                          health.ok() ? "" : absl::StrCat(" (", health.message(), ")"), "\n");
      break;
  }
  WriteAll(context.out, text);
  std::fflush(context.out);
  return health.ok() ? kExitOk : kExitUnreachable;
}

}  // namespace shapeid
