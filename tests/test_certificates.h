#ifndef SHAPEID_TESTS_TEST_CERTIFICATES_H_
#define SHAPEID_TESTS_TEST_CERTIFICATES_H_

// Throw-away certificates for the security tests, made once per test binary with the openssl
// CLI by tests/make_test_certificates.sh (see there for what each file is). Needs
// SHAPEID_SOURCE_DIR (defined by shapeid_test()).

#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <string>

#include "gtest/gtest.h"

namespace shapeid {

class TestCertificates {
 public:
  // The directory with the files, made on first use; empty (and a test failure) if openssl
  // failed.
  static const std::string& Dir() {
    // Never destroyed, so that the exit handler can still read it.
    static const std::string* const dir = [] {
      const auto* made = new std::string(Make());
      if (!made->empty()) std::atexit(Remove);
      return made;
    }();
    return *dir;
  }
  static std::string Path(const std::string& file) { return Dir() + "/" + file; }

 private:
  static std::string Make() {
    const std::string dir = ::testing::TempDir() + "/shapeid_certs_" + std::to_string(getpid());
    const std::string command = std::string("sh '") + SHAPEID_SOURCE_DIR +
                                "/tests/make_test_certificates.sh' '" + dir + "'";
    if (std::system(command.c_str()) != 0) {
      ADD_FAILURE() << "could not make test certificates (is openssl installed? "
                       "tools/install-deps.sh): "
                    << command;
      return "";
    }
    return dir;
  }
  static void Remove() {
    [[maybe_unused]] const int ignored = std::system(("rm -rf '" + Dir() + "'").c_str());
  }
};

}  // namespace shapeid

#endif  // SHAPEID_TESTS_TEST_CERTIFICATES_H_
