#ifndef SHAPEID_CLIENT_CLI_EVAL_LOCAL_H_
#define SHAPEID_CLIENT_CLI_EVAL_LOCAL_H_

// `shapeid eval --local`: the evaluation in this process, no server. Each round builds a
// core Gallery (core/gallery) with the options a server would give a temporary gallery, so
// spec, k, weighting, scaling and reject distance mean exactly what they mean there and the
// predictions are the server's.
//
// Files are read with the CLI's readers and options (batch.read: --mesh-points,
// --drop-nonfinite). batch.jobs threads read and describe clouds concurrently (a Descriptor
// and a gallery snapshot are immutable and thread-safe); samples enter the gallery in the
// order of the round's training list whatever the threads do, so the kNN tie-break order,
// hence every answer, is the same run after run. A prediction's `seconds` is the describe
// and kNN search of that cloud, file reading excluded.

#include <memory>

#include "absl/status/statusor.h"
#include "client/cli/cli_common.h"
#include "client/cli/eval_backend.h"
#include "client/cli/eval_command.h"

namespace shapeid {

// InvalidArgument (a usage error) for options no gallery could be created with: a bad
// descriptor spec, weighting, scaling or reject distance. Nothing is read.
absl::StatusOr<std::unique_ptr<EvalBackend>> NewLocalEvalBackend(const EvalOptions& options,
                                                                 const CliContext& context);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_EVAL_LOCAL_H_
