#ifndef SHAPEID_CORE_JSON_H_
#define SHAPEID_CORE_JSON_H_

// The few JSON spellings the CLI and the server's logs write by hand (their JSON is flat and
// append-only, so a JSON library would add a dependency for no gain). Not science, but
// core/ is the one library both link.

#include <string>

#include "absl/strings/string_view.h"

namespace shapeid {

// `text` as a quoted JSON string. Control characters are escaped; a byte that is not part of
// valid UTF-8 (file names are bytes) becomes U+FFFD so that the output stays valid JSON.
std::string JsonString(absl::string_view text);

// `value` with %.17g (round-trips every double); null for NaN and infinities.
std::string JsonNumber(double value);

}  // namespace shapeid

#endif  // SHAPEID_CORE_JSON_H_
