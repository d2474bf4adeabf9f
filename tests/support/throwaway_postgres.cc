#include "tests/support/throwaway_postgres.h"

#include <pwd.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <vector>

#include "core/persistence/pg_db.h"
#include "tests/support/requirement.h"

namespace orbatlas::test {
namespace {

// The newest /usr/lib/postgresql/N/bin holding initdb, pg_ctl and postgres.
std::filesystem::path find_bin() {
  std::vector<std::filesystem::path> found;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator("/usr/lib/postgresql", ec)) {
    const auto bin = entry.path() / "bin";
    if (std::filesystem::exists(bin / "initdb") && std::filesystem::exists(bin / "pg_ctl")) found.push_back(bin);
  }
  if (found.empty()) return {};
  std::sort(found.begin(), found.end(), [](const auto& a, const auto& b) {
    return std::stoi(a.parent_path().filename().string()) < std::stoi(b.parent_path().filename().string());
  });
  return found.back();
}

std::string tail_of(const std::filesystem::path& log) {
  std::ifstream in(log);
  std::stringstream s;
  s << in.rdbuf();
  std::string text = s.str();
  return text.size() > 600 ? text.substr(text.size() - 600) : text;
}

}  // namespace

std::unique_ptr<ThrowawayPostgres> ThrowawayPostgres::start(std::string* why_not) {
  const std::filesystem::path bin = find_bin();
  if (bin.empty()) {
    *why_not =
        "PostgreSQL's server binaries are missing (/usr/lib/postgresql/*/bin; Debian package postgresql, "
        "installed by scripts/setup.sh)";
    return nullptr;
  }
  char pattern[] = "/tmp/orbatlas-pg-XXXXXX";
  if (!mkdtemp(pattern)) {
    *why_not = "cannot create a temporary folder for the cluster";
    return nullptr;
  }
  const bool root = geteuid() == 0;
  if (root) {
    const passwd* pw = getpwnam("postgres");
    if (!pw || chown(pattern, pw->pw_uid, pw->pw_gid) != 0) {
      std::filesystem::remove_all(pattern);
      *why_not = "running as root, but there is no `postgres` user to run the cluster as";
      return nullptr;
    }
  }
  chmod(pattern, 0755);  // the socket must be reachable by us when the server runs as postgres
  std::unique_ptr<ThrowawayPostgres> pg(new ThrowawayPostgres(pattern, bin, root));
  const std::string dir = pg->dir_.string();
  if (pg->run("initdb", "-D " + dir + "/data -U orbatlas -A trust -E UTF8 --no-sync", dir + "/initdb.log") != 0) {
    *why_not = "initdb failed: " + tail_of(dir + "/initdb.log");
    return nullptr;
  }
  // Only the Unix socket in our folder, fsync off (a test cluster: only an OS
  // crash could lose what it acknowledged).
  const std::string options = "-k " + dir + " -c listen_addresses='' -F";
  if (pg->run("pg_ctl", "-D " + dir + "/data -l " + dir + "/server.log -w -t 60 -o \"" + options + "\" start",
              dir + "/pg_ctl.log") != 0) {
    *why_not = "the PostgreSQL server did not start: " + tail_of(dir + "/server.log");
    return nullptr;
  }
  pg->running_ = true;
  return pg;
}

int ThrowawayPostgres::run(const std::string& binary, const std::string& args, const std::string& log) const {
  const std::string command =
      (as_postgres_ ? "runuser -u postgres -- " : "") + (bin_ / binary).string() + " " + args + " > " + log + " 2>&1";
  const int status = std::system(("cd " + dir_.string() + " && " + command).c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

ThrowawayPostgres::~ThrowawayPostgres() {
  if (running_) run("pg_ctl", "-D " + dir_.string() + "/data -m immediate -w stop", "/dev/null");
  std::error_code ec;
  std::filesystem::remove_all(dir_, ec);
}

std::string ThrowawayPostgres::conninfo(const std::string& db) const {
  return "host=" + dir_.string() + " dbname=" + db + " user=orbatlas";
}

std::string ThrowawayPostgres::uri(const std::string& db) const {
  return "postgresql://orbatlas@/" + db + "?host=" + dir_.string();  // the socket folder: no characters to escape
}

void ThrowawayPostgres::create_database(const std::string& name) {
  PgDb db(conninfo());
  db.exec("CREATE DATABASE \"" + name + "\"");
}

std::unique_ptr<ThrowawayPostgres> PostgresDatabaseTest::cluster_;
std::string PostgresDatabaseTest::skip_reason_;

void PostgresDatabaseTest::SetUpTestSuite() { cluster_ = ThrowawayPostgres::start(&skip_reason_); }

void PostgresDatabaseTest::TearDownTestSuite() { cluster_.reset(); }

void PostgresDatabaseTest::SetUp() {
  if (!cluster_) ORBATLAS_NEEDS("PostgreSQL (a throwaway cluster): " << skip_reason_);
  static int n = 0;
  std::ostringstream name;  // (a chain of string + here makes GCC 12 warn falsely, -Wrestrict)
  name << "t" << ++n;
  name_ = name.str();
  cluster_->create_database(name_);
  db_ = std::make_unique<PgDb>(cluster_->conninfo(name_));
}

}  // namespace orbatlas::test
