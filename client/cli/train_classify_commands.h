#ifndef SHAPEID_CLIENT_CLI_TRAIN_CLASSIFY_COMMANDS_H_
#define SHAPEID_CLIENT_CLI_TRAIN_CLASSIFY_COMMANDS_H_

// `shapeid train` and `shapeid classify`: batch work over files and folders.

#include <cstdint>
#include <string>
#include <vector>

#include "client/cli/batch.h"
#include "client/cli/cli_common.h"

namespace shapeid {

struct TrainOptions {
  std::string gallery;
  // Non-empty: every file given (and every cloud under a folder given) gets this label.
  // Empty: each path is a labeled folder, one sub-folder per label (<label>/train/ is used
  // where it exists, as in ModelNet's layout).
  std::string label;
  std::vector<std::string> paths;
  // "KEY=VALUE" pairs for every sample's metadata (BatchOptions::metadata once parsed).
  std::vector<std::string> metadata;
  BatchOptions batch;
};
int RunTrain(const TrainOptions& options, const CliContext& context);

struct ClassifyOptions {
  std::string gallery;
  Client::ClassifyOptions call;  // k (0: the gallery's) and exact
  int top = 3;                   // neighbors shown per file in table and csv output
  std::vector<std::string> paths;
  BatchOptions batch;
};
int RunClassify(const ClassifyOptions& options, const CliContext& context);

// One JSON Lines record for a classified file (also used by eval --predictions).
std::string ClassifyJsonLine(const std::string& file, const v1::ClassifyResponse& response,
                             double seconds);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CLI_TRAIN_CLASSIFY_COMMANDS_H_
