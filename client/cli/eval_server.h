#ifndef SHAPEID_CLIENT_CLI_EVAL_SERVER_H_
#define SHAPEID_CLIENT_CLI_EVAL_SERVER_H_

// `shapeid eval` against a server: each round trains a temporary gallery (created from
// `request`, named eval-<pid>-<microseconds>-<round>, deleted when the round is over or the
// backend destroyed, also on failure) through parallel Train streams, then classifies on
// parallel Classify calls (batch.h). With options.gallery, the existing gallery is used as
// it is. A prediction's `seconds` is the Classify call as the client sees it (network,
// describing and search; file reading excluded).

#include <memory>

#include "client/cli/cli_common.h"
#include "client/cli/eval_backend.h"
#include "client/cli/eval_command.h"
#include "shapeid/v1/shapeid.pb.h"

namespace shapeid {

// Connects to context.client.target. Null, after an error line on context.err, when the
// connection options are bad (a usage error).
std::unique_ptr<EvalBackend> NewServerEvalBackend(const EvalOptions& options,
                                                  v1::CreateGalleryRequest request,
                                                  const CliContext& context);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_EVAL_SERVER_H_
