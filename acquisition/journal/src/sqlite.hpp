// A small RAII layer over SQLite's C API for the catalog: one owner of the connection, one of
// each prepared statement, and one place (check) where SQLite's result codes become CatalogError
// naming the file, the operation and SQLite's words.
// SPDX-License-Identifier: MIT
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "scanmesh/acquisition/catalog.hpp"

namespace scanmesh::acq::detail {

class Database {
 public:
  Database(const std::string& file, bool read_only) : file_(file) {
    const int flags = read_only ? SQLITE_OPEN_READONLY : SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE;
    const int rc = sqlite3_open_v2(file.c_str(), &db_, flags | SQLITE_OPEN_NOMUTEX, nullptr);
    if (rc != SQLITE_OK) {
      const std::string msg = db_ != nullptr ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
      sqlite3_close_v2(db_);
      db_ = nullptr;
      throw CatalogError("catalog " + file + ": cannot open: " + msg);
    }
    sqlite3_extended_result_codes(db_, 1);
    check(sqlite3_busy_timeout(db_, 5000), "setting the busy timeout");
  }
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;
  ~Database() { sqlite3_close_v2(db_); }

  [[nodiscard]] sqlite3* get() const noexcept { return db_; }
  [[nodiscard]] const std::string& file() const noexcept { return file_; }

  /// Throws CatalogError unless rc is SQLITE_OK, SQLITE_ROW or SQLITE_DONE.
  void check(int rc, std::string_view what) const {
    if (rc == SQLITE_OK || rc == SQLITE_ROW || rc == SQLITE_DONE) return;
    throw CatalogError("catalog " + file_ + ": " + std::string(what) +
                       " failed: " + sqlite3_errmsg(db_) + " (" + sqlite3_errstr(rc) + ")");
  }

  void exec(const std::string& sql, std::string_view what) const {
    check(sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, nullptr), what);
  }

 private:
  std::string file_;
  sqlite3* db_ = nullptr;
};

class Statement {
 public:
  Statement(const Database& db, std::string_view sql) : db_(db) {
    db.check(
        sqlite3_prepare_v2(db.get(), sql.data(), static_cast<int>(sql.size()), &stmt_, nullptr),
        "preparing a statement");
  }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  ~Statement() { sqlite3_finalize(stmt_); }

  Statement& bind(int i, std::int64_t v) {
    db_.check(sqlite3_bind_int64(stmt_, i, v), "binding a value");
    return *this;
  }
  Statement& bind(int i, std::string_view v) {
    db_.check(sqlite3_bind_text(stmt_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT),
              "binding a value");
    return *this;
  }
  Statement& bind_null(int i) {
    db_.check(sqlite3_bind_null(stmt_, i), "binding a value");
    return *this;
  }
  /// Steps once: true when a row is there.
  bool step(std::string_view what) {
    const int rc = sqlite3_step(stmt_);
    db_.check(rc, what);
    return rc == SQLITE_ROW;
  }
  [[nodiscard]] std::int64_t int64(int col) const { return sqlite3_column_int64(stmt_, col); }
  [[nodiscard]] std::string text(int col) const {
    const auto* p = sqlite3_column_text(stmt_, col);
    return p == nullptr ? std::string()
                        : std::string(reinterpret_cast<const char*>(p),
                                      static_cast<std::size_t>(sqlite3_column_bytes(stmt_, col)));
  }

 private:
  const Database& db_;
  sqlite3_stmt* stmt_ = nullptr;
};

/// BEGIN IMMEDIATE ... COMMIT, rolled back when left by an exception.
class Transaction {
 public:
  explicit Transaction(const Database& db) : db_(db) {
    db.exec("BEGIN IMMEDIATE", "starting a transaction");
  }
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  void commit() {
    db_.exec("COMMIT", "committing");
    done_ = true;
  }
  ~Transaction() {
    if (!done_) sqlite3_exec(db_.get(), "ROLLBACK", nullptr, nullptr, nullptr);
  }

 private:
  const Database& db_;
  bool done_ = false;
};

}  // namespace scanmesh::acq::detail
