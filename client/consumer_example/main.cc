// Links against the installed shapeid::client and shapeid::io: reads a PCD file with the
// package's readers, then makes one call to a port where nothing listens; the call must come
// back UNAVAILABLE (the client works, the server is absent).
#include <cstdio>
#include <fstream>
#include <iostream>

#include "shapeid/client/client.h"
#include "shapeid/core/io/point_cloud_reader.h"

int main() {
  const char* path = "consumer_example_cloud.pcd";
  std::ofstream(path) << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                         "WIDTH 4\nHEIGHT 1\nPOINTS 4\nDATA ascii\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n";
  absl::StatusOr<shapeid::ReadResult> read = shapeid::ReadPointCloud(path);
  std::remove(path);
  if (!read.ok() || read->cloud.size() != 4) {
    std::cerr << "reading the PCD failed: " << read.status() << "\n";
    return 1;
  }

  shapeid::ClientOptions options;
  options.target = "127.0.0.1:1";
  options.max_attempts = 1;
  options.deadline = absl::Seconds(5);
  auto client = shapeid::Client::Connect(options);
  if (!client.ok()) {
    std::cerr << client.status() << "\n";
    return 1;
  }
  auto result = (*client)->Describe(read->cloud);
  std::cout << "read " << read->cloud.size()
            << " points; Describe without a server: " << result.status() << "\n";
  return absl::IsUnavailable(result.status()) ? 0 : 1;
}
