// Links against the installed shapeid::client and makes one call to a port where nothing
// listens: the call must come back UNAVAILABLE (the client works, the server is absent).
#include <iostream>

#include "client/client.h"
#include "core/point_cloud.h"

int main() {
  shapeid::ClientOptions options;
  options.target = "127.0.0.1:1";
  options.max_attempts = 1;
  options.deadline = absl::Seconds(5);
  auto client = shapeid::Client::Connect(options);
  if (!client.ok()) {
    std::cerr << client.status() << "\n";
    return 1;
  }
  shapeid::PointCloud cloud({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}});
  auto result = (*client)->Describe(cloud);
  std::cout << "Describe without a server: " << result.status() << "\n";
  return absl::IsUnavailable(result.status()) ? 0 : 1;
}
