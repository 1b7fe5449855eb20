#ifndef SHAPEID_BENCH_SOAK_SOAK_CLIENT_H_
#define SHAPEID_BENCH_SOAK_SOAK_CLIENT_H_

// One simulated robot of the soak test: a channel and TCP connection of its own, a gallery
// "soak-NN" and a scratch gallery "soak-NN-scratch" that only it changes, so it knows exactly
// what each answer must say. Raw stubs rather than shapeid::Client: the client library retries
// UNAVAILABLE (which would hide errors) and shares one TCP connection among its channels.
// Not thread-safe: one thread drives one client.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/time/time.h"
#include "bench/soak/cloud_pool.h"
#include "bench/soak/recording.h"
#include "grpcpp/grpcpp.h"
#include "shapeid/v1/shapeid.grpc.pb.h"

namespace shapeid::soak {

struct ClientSettings {
  size_t gallery_samples = 64;  // trim back to 3/4 of this once a Train passes it
  absl::Duration deadline = absl::Seconds(30);
  std::string api_key;    // sent with every call when set
  std::string caller_id;  // the shapeid-caller-id metadata when set
};

// Sets `context`'s deadline and the key and caller id `settings` give.
void PrepareContext(const ClientSettings& settings, grpc::ClientContext& context);

class SoakClient {
 public:
  // Client `index` (0-based) of the server at `address`, drawing clouds from `pool`, which
  // must outlive it.
  SoakClient(int index, const std::string& address, const Pool& pool, ClientSettings settings);

  // The galleries and their first samples. Not timed.
  absl::Status SetUp();
  // The next request: what a previous step requires, else a weighted draw.
  Kind Next();
  // Makes one request of `kind` and checks the answer against what the client holds; any
  // non-OK status or failed check is an error.
  absl::Status Run(Kind kind);
  // After an error: what the server holds now (a failed call changes nothing, but a deadline
  // may pass after the server committed), read back from an export and GetGallery.
  absl::Status Resync();

 private:
  struct Held {
    uint64_t id;
    std::string label;
    size_t cloud;  // index in Pool::xyz; SIZE_MAX if unknown (after a resync)
  };

  // OK if `ok`, else Internal "check failed: `what`".
  static absl::Status Check(bool ok, const std::string& what);

  void SetDeadline(grpc::ClientContext& context) const { PrepareContext(settings_, context); }
  size_t RandomCloud();
  absl::Status CreateGallery(const std::string& name, uint32_t k);
  absl::Status Train(bool scratch, int n);
  absl::Status RemoveSamples();
  absl::Status Classify(bool stream);
  absl::Status Describe(bool stream);
  absl::Status CheckGallery(const v1::Gallery& gallery) const;
  absl::Status GetGallery();
  absl::Status ListGalleries();
  absl::Status ReadExport(std::vector<v1::GalleryExportChunk>* chunks);
  absl::Status Export();
  absl::Status DeleteScratch();
  absl::Status ImportScratch();
  absl::Status RecognizeScene();

  const Pool& pool_;
  const ClientSettings settings_;
  std::mt19937 rng_;
  const std::string name_, scratch_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::ShapeId::Stub> stub_;

  std::string spec_;       // the gallery's canonical spec
  size_t dimension_ = 0;   // and descriptor length
  std::deque<Held> held_;  // the gallery's samples, oldest first
  uint64_t next_id_;
  bool scratch_exists_ = false;
  uint64_t scratch_count_ = 0;
  bool train_scratch_next_ = false;
  std::deque<Kind> pending_;
  int removals_ = 0;
  int recreations_ = 0;
  std::vector<v1::GalleryExportChunk> last_export_;
  std::map<size_t, std::vector<float>> descriptors_;  // pool cloud -> first answer
};

}  // namespace shapeid::soak

#endif  // SHAPEID_BENCH_SOAK_SOAK_CLIENT_H_
