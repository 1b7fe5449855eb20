#include "client/cli/eval_command.h"

#include <cstdio>
#include <fstream>
#include <memory>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "client/cli/eval_backend.h"
#include "client/cli/eval_local.h"
#include "client/cli/eval_report.h"
#include "client/cli/eval_server.h"
#include "core/version.h"

namespace shapeid {
namespace {

// Prints the run in context.format and writes the HTML report if asked.
int WriteEvalResults(const EvalRun& run, const EvalOptions& options, const CliContext& context) {
  const EvalMetrics metrics = ComputeEvalMetrics(run);
  std::string text;
  switch (context.format) {
    case OutputFormat::kJson:
      text = FormatEvalJson(run, metrics, options.with_predictions);
      break;
    case OutputFormat::kCsv:
      text = FormatEvalCsv(metrics);
      break;
    case OutputFormat::kTable:
      text = FormatEvalTable(run, metrics);
      break;
  }
  bool written = WriteAll(context.out, text);
  written &= std::fflush(context.out) == 0;
  if (!options.report_html.empty()) {
    std::ofstream report(options.report_html, std::ios::binary | std::ios::trunc);
    report << RenderEvalHtml(run, metrics, ErrorPicturesFromFiles(options.batch.read));
    report.close();
    if (!report) {
      WriteAll(context.err,
               absl::StrCat("shapeid: eval: cannot write the report ", options.report_html, "\n"));
      return kExitSomeInputsFailed;
    }
    if (context.progress != ProgressMode::kOff) {
      WriteAll(context.err, absl::StrCat("report written to ", options.report_html, "\n"));
    }
  }
  if (!written) {
    WriteAll(context.err, "shapeid: cannot write the output\n");
    return kExitSomeInputsFailed;
  }
  return run.failed_files.empty() ? kExitOk : kExitSomeInputsFailed;
}

}  // namespace

int RunEval(const EvalOptions& options, const CliContext& context) {
  const auto usage = [&](const absl::Status& status) {
    PrintError(context.err, "eval", status);
    return kExitUsage;
  };
  if (options.local && !options.gallery.empty()) {
    WriteAll(context.err,
             "shapeid: eval: --gallery needs the server; drop --local (or drop --gallery to "
             "evaluate on temporary in-process galleries)\n");
    return kExitUsage;
  }
  if (!options.local && options.create.learn == "mlp") {
    WriteAll(context.err,
             "shapeid: eval: --learn mlp needs --local: servers do not fit trained heads yet\n");
    return kExitUsage;
  }
  absl::StatusOr<EvalPlan> plan =
      PlanEval(options.dataset, !options.gallery.empty(), options.folds, options.seed);
  if (!plan.ok()) return usage(plan.status());
  const bool unsupported_failed = ReportUnsupportedFiles(context.err, "eval", plan->unsupported,
                                                         options.batch.skip_unsupported);
  absl::StatusOr<v1::CreateGalleryRequest> request = CreateGalleryRequestFor(options.create);
  if (!request.ok()) return usage(request.status());

  std::unique_ptr<EvalBackend> backend;
  if (options.local) {
    absl::StatusOr<std::unique_ptr<EvalBackend>> local = NewLocalEvalBackend(options, context);
    if (!local.ok()) return usage(local.status());
    backend = std::move(local).value();
  } else {
    backend = NewServerEvalBackend(options, std::move(request).value(), context);
    if (backend == nullptr) return kExitUsage;
  }
  const auto stopped = [&](const EvalStep& step) {
    if (backend->target().empty()) {  // in-process: no call to name
      PrintError(context.err, step.what, step.status);
    } else {
      PrintCallError(context, step.what, step.status);
    }
    return ExitCodeForStatus(step.status);
  };

  EvalRun run;
  run.mode = plan->mode;
  run.dataset = options.dataset;
  run.seed = options.seed;
  run.folds = plan->folds;
  run.started = absl::FormatTime("%Y-%m-%dT%H:%M:%SZ", absl::Now(), absl::UTCTimeZone());
  run.server = backend->target();
  run.client_version = kShapeidVersion;
  const std::vector<EvalRound>& rounds = plan->rounds;
  for (size_t r = 0; r < rounds.size(); ++r) {
    const int round = static_cast<int>(r);
    const std::string phase =
        rounds.size() > 1 ? absl::StrCat("fold ", r + 1, "/", rounds.size(), " ") : "";
    const uint64_t trained_before = run.train_samples;
    EvalStep step;
    {
      Progress progress(context.err, context.progress, phase + "train", rounds[r].train.size());
      step = backend->Train(round, rounds[r].train, progress, run);
    }
    if (!step.ok()) return stopped(step);
    if (run.mode != "gallery" && run.train_samples == trained_before) {
      return stopped({"eval", absl::FailedPreconditionError(
                                  "no training file could be used; nothing to evaluate")});
    }
    {
      Progress progress(context.err, context.progress, phase + "test", rounds[r].test.size());
      step = backend->Test(round, rounds[r].test, progress, run);
    }
    if (!step.ok()) return stopped(step);
  }
  backend->IdentifyServer(run);  // asked last: by now the server has answered every call
  backend.reset();               // temporary galleries go before the results are printed
  const int code = WriteEvalResults(run, options, context);
  return code == kExitOk && unsupported_failed ? kExitSomeInputsFailed : code;
}

}  // namespace shapeid
