#pragma once
// Who may call the API: named clients, each with a bearer token (kept as its
// SHA-256, never the token itself) and a role.
//
//   reader    GET only: lists, statuses, maps, the viewer's data, metrics;
//   device    a reader that may also start sessions, drive its own (frames, IMU,
//             finish) and localise images;
//   operator  everything: uploads, any session (frames and IMU only its own).
//
// The clients file (`orbatlas-server --clients FILE`) has one client per line,
// `name role sha256:<64 hex digits of the token's SHA-256>`; blank lines and
// `#` comments are skipped. `printf %s "$TOKEN" | sha256sum` gives the digits.
// A single `--token` is the one client "token", an operator.
#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace orbatlas {

enum class ClientRole { kReader, kDevice, kOperator };
const char* client_role_name(ClientRole role);

struct ApiClient {
  std::string name;
  ClientRole role = ClientRole::kOperator;
};

class ClientCredentials {
 public:
  using Digest = std::array<unsigned char, 32>;

  ClientCredentials() = default;  // no clients: the API is open (a loopback server)
  // Throws Error naming the file and line of a malformed entry, an unknown role,
  // a name used twice, or a file with no client.
  static ClientCredentials from_file(const std::filesystem::path& file);
  static ClientCredentials single_token(const std::string& token);

  bool open() const { return clients_.empty(); }
  std::size_t size() const { return clients_.size(); }
  // The client an `Authorization` header names (`Bearer <token>`, the scheme in
  // any letter case); none when absent, malformed or unknown. Every client's
  // digest is compared in full, so the time says nothing about which is near.
  std::optional<ApiClient> authenticate(std::string_view authorization) const;

 private:
  struct Entry {
    ApiClient client;
    Digest digest{};
  };
  std::vector<Entry> clients_;
};

ClientCredentials::Digest sha256(std::string_view text);

// Whether `role` may send `method` to `path` (ownership is checked by the routes).
bool role_allows(ClientRole role, const std::string& method, const std::string& path);

}  // namespace orbatlas
