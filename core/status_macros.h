#ifndef SHAPEID_CORE_STATUS_MACROS_H_
#define SHAPEID_CORE_STATUS_MACROS_H_

// Abseil 20220623 (Debian 12) has no ABSL_RETURN_IF_ERROR / ASSIGN_OR_RETURN; these are the
// small local equivalents.

#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

#define SHAPEID_RETURN_IF_ERROR(expr)                  \
  do {                                                 \
    ::absl::Status shapeid_status_ = (expr);           \
    if (!shapeid_status_.ok()) return shapeid_status_; \
  } while (false)

#define SHAPEID_STATUS_CONCAT_INNER_(a, b) a##b
#define SHAPEID_STATUS_CONCAT_(a, b) SHAPEID_STATUS_CONCAT_INNER_(a, b)

// SHAPEID_ASSIGN_OR_RETURN(auto x, MakeX()); declares or assigns x from an absl::StatusOr,
// returning its status from the enclosing function when it is an error.
#define SHAPEID_ASSIGN_OR_RETURN(lhs, rexpr) \
  SHAPEID_ASSIGN_OR_RETURN_IMPL_(SHAPEID_STATUS_CONCAT_(shapeid_statusor_, __LINE__), lhs, rexpr)

#define SHAPEID_ASSIGN_OR_RETURN_IMPL_(statusor, lhs, rexpr) \
  auto statusor = (rexpr);                                   \
  if (!statusor.ok()) return std::move(statusor).status();   \
  lhs = std::move(statusor).value()

#endif  // SHAPEID_CORE_STATUS_MACROS_H_
