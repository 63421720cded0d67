// The results history in PostgreSQL, through libpqxx, for a plant whose cells write to one
// database. Values are sent as quoted literals (the connection's own quoting) rather than as
// parameters: the same statement text then serves the libpqxx versions Debian ships.
#include "schema.hpp"
#include "stampscan/results/results_store.hpp"

#include <pqxx/pqxx>

#include <cmath>
#include <cstdio>
#include <regex>

namespace stampscan::results {

namespace {

// A text literal: the connection's escaping inside single quotes. (Not quote(): with GCC 12 it
// trips a false -Wrestrict warning inside libpqxx's header.)
std::string quoted(pqxx::transaction_base& transaction, const std::string& s) {
  std::string out = "'";
  out.append(transaction.esc(s)).append("'");
  return out;
}

// Serialises migrations of one database across the cells that share it (any fixed number will do,
// as long as it is always the same one).
constexpr long long kMigrationLockKey = 0x5354414d50;  // "STAMP"

// The URL for messages: the password replaced, whether in the authority or as a parameter.
std::string withoutPassword(const std::string& url) {
  static const std::regex authority(R"(^(postgres(?:ql)?://[^:/@?]*):[^@/?]*@)");
  static const std::regex parameter(R"(([?&]password=)[^&]*)");
  return std::regex_replace(std::regex_replace(url, authority, "$1:***@"), parameter, "$1***");
}

// A server that does not answer (a host down, a firewall that drops) is given up after a few
// seconds, not after the system's TCP timeout of minutes: the URL's own connect_timeout otherwise.
std::string withConnectTimeout(const std::string& url) {
  if (url.find("connect_timeout=") != std::string::npos) return url;
  return url + (url.find('?') == std::string::npos ? "?" : "&") + "connect_timeout=5";
}

std::string literal(const std::optional<double>& v) {
  if (!v || !std::isfinite(*v)) return "NULL";
  char text[40];
  std::snprintf(text, sizeof text, "%.17g", *v);
  return text;
}

// The values of a query are only known once its SQL is built: the placeholders are numbered
// first (\x01 i \x02), then each is filled with its value, quoted.
std::string numberedPlaceholder(std::size_t i) { return std::string("\x01").append(std::to_string(i)).append("\x02"); }

std::string fillPlaceholders(pqxx::transaction_base& transaction, const std::string& numbered,
                             const std::vector<std::string>& values) {
  std::string sql;
  for (std::size_t at = 0; at < numbered.size();) {
    if (numbered[at] != '\x01') {
      sql += numbered[at++];
      continue;
    }
    const std::size_t end = numbered.find('\x02', at);
    sql += quoted(transaction, values.at(std::stoul(numbered.substr(at + 1, end - at - 1))));
    at = end + 1;
  }
  return sql;
}

class PostgresStore final : public ResultsStore {
 public:
  PostgresStore(const std::string& url, const StoreOptions& options)
      : ResultsStore(withoutPassword(url)), options_(options) {
    try {
      connection_ = std::make_unique<pqxx::connection>(withConnectTimeout(url));
      pqxx::nontransaction session(*connection_);
      // A write waits at most this long for a lock another cell holds; then the statement fails.
      session.exec("SET lock_timeout = " + std::to_string(options.lock_timeout.count()));
      if (options.read_only) session.exec("SET default_transaction_read_only = on");
    } catch (const std::exception& e) {
      fail("cannot connect", e);
    }
    try {
      const int version = readVersion();
      if (version > kSchemaVersion) throw ResultsError(schema::newerSchemaMessage(location(), version));
      if (version < kSchemaVersion) {
        if (options.read_only)
          throw ResultsError(location() + ": results database of schema version " + std::to_string(version) +
                             ", older than this program's " + std::to_string(kSchemaVersion) +
                             "; record a run in it to migrate it first");
        migrate();
      }
    } catch (const ResultsError&) {
      throw;
    } catch (const std::exception& e) {
      fail("cannot be read", e);
    }
  }

 protected:
  void upsertRuns(const std::vector<RunRow>& runs) override {
    const RunRow* current = &runs.front();
    try {
      pqxx::work transaction(*connection_);
      const std::string recorded = schema::nowUtc();
      for (const RunRow& run : runs) {
        current = &run;
        transaction.exec(upsertStatement(transaction, run, recorded));
      }
      transaction.commit();
    } catch (const std::exception& e) {
      fail(runs.size() == 1 ? "run " + current->run_id + " not recorded"
                            : std::to_string(runs.size()) + " runs not recorded (at run " + current->run_id + ")",
           e);
    }
  }

  static std::string upsertStatement(pqxx::transaction_base& transaction, const RunRow& run,
                                     const std::string& recorded) {
    struct Literals {
      pqxx::transaction_base& transaction;
      std::vector<std::string> v;
      void text(const std::string& s) { v.push_back(quoted(transaction, s)); }
      void number(const std::optional<double>& n) { v.push_back(literal(n)); }
      void count(const std::optional<std::int64_t>& n) { v.push_back(n ? std::to_string(*n) : "NULL"); }
    } literals{transaction, {}};
    const std::string status = toString(run.status);
    schema::visitRunColumns(run, status, literals);
    literals.text(recorded);
    return schema::upsertSql([&v = literals.v](std::size_t i) { return v.at(i); });
  }

  std::vector<RunRow> selectRuns(const RunFilter& filter) const override {
    std::vector<RunRow> runs;
    try {
      pqxx::read_transaction transaction(*connection_);
      std::vector<std::string> values;
      const std::string numbered = schema::selectSql(filter, numberedPlaceholder, values);
      const pqxx::result rows = transaction.exec(fillPlaceholders(transaction, numbered, values));
      runs.reserve(rows.size());
      for (const pqxx::row& row : rows) {
        RunRow& r = runs.emplace_back();
        struct Reader {
          const pqxx::row& row;
          pqxx::row::size_type c = 0;
          void text(std::string& out) {
            const pqxx::field f = row[c++];
            out = f.is_null() ? std::string() : std::string(f.c_str());
          }
          void number(std::optional<double>& out) {
            const pqxx::field f = row[c++];
            if (!f.is_null()) out = f.as<double>();
          }
          void count(std::optional<std::int64_t>& out) {
            const pqxx::field f = row[c++];
            if (!f.is_null()) out = f.as<long long>();
          }
        } reader{row};
        std::string status;
        schema::visitRunColumns(r, status, reader);
        r.status = runStatusFromString(status);
      }
    } catch (const ResultsError& e) {
      throw ResultsError(location() + ": " + e.what());
    } catch (const std::exception& e) {
      fail("cannot be queried", e);
    }
    return runs;
  }

  int storedSchemaVersion() const override {
    try {
      return readVersion();
    } catch (const std::exception& e) {
      fail("cannot be read", e);
    }
  }

  void upsertCalibration(const CalibrationRow& row) override {
    try {
      pqxx::work transaction(*connection_);
      std::vector<std::string> v;
      for (const std::string& value : schema::calibrationValues(row)) v.push_back(quoted(transaction, value));
      v.push_back(quoted(transaction, schema::nowUtc()));
      transaction.exec(schema::calibrationUpsertSql([&v](std::size_t i) { return v.at(i); }));
      transaction.commit();
    } catch (const std::exception& e) {
      fail("calibration " + row.record_id + " not recorded", e);
    }
  }

  std::vector<CalibrationRow> selectCalibrations(const std::string& kind, std::size_t limit) const override {
    std::vector<CalibrationRow> out;
    try {
      pqxx::read_transaction transaction(*connection_);
      std::vector<std::string> values;
      const std::string numbered = schema::calibrationSelectSql(kind, limit, numberedPlaceholder, values);
      for (const pqxx::row& row : transaction.exec(fillPlaceholders(transaction, numbered, values))) {
        CalibrationRow& r = out.emplace_back();
        pqxx::row::size_type c = 0;
        for (std::string* field : {&r.record_id, &r.kind, &r.created_utc, &r.cell, &r.verdict, &r.accepted_by, &r.summary,
                                   &r.record_file, &r.record_json}) {
          const pqxx::field f = row[c++];
          *field = f.is_null() ? std::string() : std::string(f.c_str());
        }
      }
    } catch (const std::exception& e) {
      fail("cannot be queried", e);
    }
    return out;
  }

 private:
  int readVersion() const {
    pqxx::read_transaction transaction(*connection_);
    const pqxx::result table = transaction.exec("SELECT to_regclass('schema_version') IS NOT NULL");
    if (!table[0][0].as<bool>()) return 0;
    const pqxx::result version = transaction.exec("SELECT max(version) FROM schema_version");
    return version[0][0].is_null() ? 0 : version[0][0].as<int>();
  }

  void migrate() {
    pqxx::work transaction(*connection_);
    transaction.exec("SELECT pg_advisory_xact_lock(" + std::to_string(kMigrationLockKey) + ")");
    transaction.exec(schema::kCreateVersionTable);
    // Read again under the lock: another cell may have migrated meanwhile.
    const pqxx::result rows = transaction.exec("SELECT max(version) FROM schema_version");
    const int found = rows[0][0].is_null() ? 0 : rows[0][0].as<int>();
    if (found > kSchemaVersion) throw ResultsError(schema::newerSchemaMessage(location(), found));
    for (const std::string& statement : schema::migrationStatements(found)) transaction.exec(statement);
    transaction.commit();
  }

  [[noreturn]] void fail(const std::string& what, const std::exception& e) const {
    // libpq's messages run over several lines; the error is one line.
    std::string why;
    for (const char* c = e.what(); *c; ++c) {
      const bool space = *c == '\n' || *c == '\t' || *c == ' ';
      if (!space) why += *c;
      else if (!why.empty() && why.back() != ' ') why += ' ';
    }
    while (!why.empty() && why.back() == ' ') why.pop_back();
    if (const auto* sql = dynamic_cast<const pqxx::sql_error*>(&e)) {
      const std::string state = sql->sqlstate();
      if (state == "55P03")
        why = "locked by another connection (waited " + std::to_string(options_.lock_timeout.count()) + " ms): " + why;
      else if (state == "25006") why = "read-only: " + why;
      else if (state == "53100") why = "the database's disk is full: " + why;
    }
    throw ResultsError(location() + ": " + what + ": " + why);
  }

  StoreOptions options_;
  std::unique_ptr<pqxx::connection> connection_;
};

}  // namespace

std::unique_ptr<ResultsStore> openPostgresStore(const std::string& url, const StoreOptions& options) {
  return std::make_unique<PostgresStore>(url, options);
}

std::string locationForMessages(const std::string& runs_dir_or_url) {
  return isDatabaseUrl(runs_dir_or_url) ? withoutPassword(runs_dir_or_url) : runs_dir_or_url;
}

}  // namespace stampscan::results
