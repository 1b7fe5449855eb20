#ifndef SHAPEID_CLIENT_CLI_EVAL_REPORT_H_
#define SHAPEID_CLIENT_CLI_EVAL_REPORT_H_

// The HTML report of a labeled evaluation (`shapeid eval --report`): one self-contained page
// rendered from the run and its metrics (client/cli/eval_metrics.h).

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "absl/strings/string_view.h"
#include "client/cli/eval_metrics.h"
#include "core/io/read_options.h"

namespace shapeid {

// Pictures (cloud_picture.h) of one misclassified test cloud and of the training sample
// nearest to it, as PNG files. A PNG left empty comes with the reason, in plain words.
struct ErrorPictures {
  std::string test_png;
  std::string test_missing;
  std::string neighbor_png;
  std::string neighbor_missing;
};
using ErrorPictureSource = std::function<ErrorPictures(const EvalPrediction&)>;

// The page pictures the first this many errors: each picture costs a few KB.
inline constexpr size_t kMaxErrorPictures = 50;

// A self-contained HTML page (inline CSS, pictures as data: URIs, no scripts or external
// resources): a header (dataset, mode, gallery, descriptor spec, k, start time, server,
// client and server versions), headline figures, per-class table, the confusion matrix as a
// colored grid (truth rows only; cell shade = share of the row), the errors (first 500:
// file, truth, predicted, the nearest training sample's id, label, distance and training
// file; the vote share only when k > 1), for the first kMaxErrorPictures of them a picture of
// the test cloud beside one of its nearest training sample (from `pictures`; none when null),
// the failed files (first 500), the timings. Every string from the run is escaped.
std::string RenderEvalHtml(const EvalRun& run, const EvalMetrics& metrics,
                           const ErrorPictureSource& pictures = nullptr);

// The misclassified predictions in the page's order: grouped by truth, then by predicted
// label, each group in the run's order.
std::vector<const EvalPrediction*> ReportErrors(const EvalRun& run);

// Pictures made by reading the test file and the nearest neighbor's training file with the
// CLI's readers (ReadInputCloud, `read`). A training file met again is not read twice.
ErrorPictureSource ErrorPicturesFromFiles(const ReadOptions& read);

// `text` escaped for HTML text and attribute values (& < > " ').
std::string HtmlEscape(absl::string_view text);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_EVAL_REPORT_H_
