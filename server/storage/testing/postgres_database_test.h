#ifndef SHAPEID_SERVER_STORAGE_TESTING_POSTGRES_DATABASE_TEST_H_
#define SHAPEID_SERVER_STORAGE_TESTING_POSTGRES_DATABASE_TEST_H_

#include <memory>
#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "gtest/gtest.h"
#include "server/storage/pg_connection.h"
#include "server/storage/testing/postgres_instance.h"

namespace shapeid {

// A test fixture over one private PostgreSQL for the whole suite (initdb takes a second or
// two); each test works in a fresh database of its own, `prefix` + the test's name, at
// conninfo_. Without PostgreSQL the tests skip, or fail where PostgresInstance::Required().
class PostgresDatabaseTest : public ::testing::Test {
 protected:
  explicit PostgresDatabaseTest(std::string prefix) : prefix_(std::move(prefix)) {}

  static void SetUpTestSuite() {
    absl::StatusOr<std::unique_ptr<PostgresInstance>> started = PostgresInstance::Start();
    if (started.ok()) {
      pg_ = started->release();
    } else {
      start_error_ = new absl::Status(started.status());
    }
  }
  static void TearDownTestSuite() {
    delete pg_;
    pg_ = nullptr;
  }

  void SetUp() override {
    if (pg_ == nullptr) {
      if (PostgresInstance::Required()) FAIL() << *start_error_;
      GTEST_SKIP() << "no PostgreSQL to test against: " << *start_error_;
    }
    const std::string db =
        absl::StrCat(prefix_, ::testing::UnitTest::GetInstance()->current_test_info()->name());
    auto admin = PgConnection::Connect(pg_->conninfo());
    ASSERT_TRUE(admin.ok()) << admin.status();
    ASSERT_TRUE((*admin)->Exec("drop", absl::StrCat("DROP DATABASE IF EXISTS \"", db, "\"")).ok());
    ASSERT_TRUE((*admin)->Exec("create", absl::StrCat("CREATE DATABASE \"", db, "\"")).ok());
    conninfo_ = absl::StrCat("postgresql://shapeid@127.0.0.1:", pg_->port(), "/", db);
  }

  inline static PostgresInstance* pg_ = nullptr;
  inline static absl::Status* start_error_ = nullptr;
  std::string conninfo_;

 private:
  std::string prefix_;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_STORAGE_TESTING_POSTGRES_DATABASE_TEST_H_
