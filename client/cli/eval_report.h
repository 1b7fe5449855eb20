#ifndef SHAPEID_CLIENT_CLI_EVAL_REPORT_H_
#define SHAPEID_CLIENT_CLI_EVAL_REPORT_H_

// The HTML report of a labelled evaluation (`shapeid eval --report-html`): one self-contained
// page rendered from the run and its metrics (client/cli/eval_metrics.h).

#include <string>

#include "absl/strings/string_view.h"
#include "client/cli/eval_metrics.h"

namespace shapeid {

// A self-contained HTML page (inline CSS, no scripts or external resources): headline
// figures, per-class table, the confusion matrix as a coloured grid (truth rows only; cell
// shade = share of the row), the list of errors (file, truth, predicted; first 500), failed
// files (first 500), the run's parameters. Every string from the run is escaped.
std::string RenderEvalHtml(const EvalRun& run, const EvalMetrics& metrics);

// `text` escaped for HTML text and attribute values (& < > " ').
std::string HtmlEscape(absl::string_view text);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_EVAL_REPORT_H_
