#include "server/http/client_credentials.h"

#include <openssl/evp.h>

#include <cctype>
#include <fstream>
#include <regex>
#include <sstream>

#include "core/common/error.h"

namespace orbatlas {
namespace {

std::string lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

std::optional<ClientCredentials::Digest> parse_digest(const std::string& text) {
  if (text.size() != 7 + 64 || text.compare(0, 7, "sha256:") != 0) return std::nullopt;
  ClientCredentials::Digest d{};
  for (std::size_t i = 0; i < 32; ++i) {
    unsigned value = 0;
    for (std::size_t k = 0; k < 2; ++k) {
      const char c = static_cast<char>(std::tolower(static_cast<unsigned char>(text[7 + 2 * i + k])));
      if (c >= '0' && c <= '9')
        value = value * 16 + static_cast<unsigned>(c - '0');
      else if (c >= 'a' && c <= 'f')
        value = value * 16 + static_cast<unsigned>(c - 'a' + 10);
      else
        return std::nullopt;
    }
    d[i] = static_cast<unsigned char>(value);
  }
  return d;
}

std::optional<ClientRole> parse_role(const std::string& text) {
  if (text == "reader") return ClientRole::kReader;
  if (text == "device") return ClientRole::kDevice;
  if (text == "operator") return ClientRole::kOperator;
  return std::nullopt;
}

}  // namespace

const char* client_role_name(ClientRole role) {
  switch (role) {
    case ClientRole::kReader:
      return "reader";
    case ClientRole::kDevice:
      return "device";
    case ClientRole::kOperator:
      return "operator";
  }
  return "?";
}

ClientCredentials::Digest sha256(std::string_view text) {
  ClientCredentials::Digest d{};
  unsigned int length = 0;
  if (EVP_Digest(text.data(), text.size(), d.data(), &length, EVP_sha256(), nullptr) != 1 || length != d.size())
    throw Error("SHA-256 failed (OpenSSL)");
  return d;
}

ClientCredentials ClientCredentials::from_file(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw Error("clients file " + file.string() + ": cannot be read");
  ClientCredentials c;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const std::string where = file.string() + ":" + std::to_string(number) + ": ";
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    std::istringstream fields(line);
    std::string name, role, digest, extra;
    if (!(fields >> name)) continue;  // blank
    if (!(fields >> role >> digest) || (fields >> extra))
      throw Error(where + "expected 'name role sha256:<hex>', got '" + line.substr(0, 120) + "'");
    if (!std::regex_match(name, std::regex("[A-Za-z0-9._-]{1,64}")))
      throw Error(where + "a client name is 1-64 letters, digits, '.', '_' or '-', not '" + name.substr(0, 80) + "'");
    const auto parsed_role = parse_role(role);
    if (!parsed_role) throw Error(where + "role '" + role.substr(0, 40) + "' is none of reader, device, operator");
    const auto parsed_digest = parse_digest(lower(digest));
    if (!parsed_digest)
      throw Error(where + "the token is given as sha256:<64 hex digits> (printf %s \"$TOKEN\" | sha256sum)");
    for (const Entry& e : c.clients_)
      if (e.client.name == name) throw Error(where + "client '" + name + "' is named twice");
    c.clients_.push_back({ApiClient{name, *parsed_role}, *parsed_digest});
  }
  if (c.clients_.empty()) throw Error("clients file " + file.string() + ": no client in it");
  return c;
}

ClientCredentials ClientCredentials::single_token(const std::string& token) {
  ClientCredentials c;
  if (!token.empty()) c.clients_.push_back({ApiClient{"token", ClientRole::kOperator}, sha256(token)});
  return c;
}

std::optional<ApiClient> ClientCredentials::authenticate(std::string_view authorization) const {
  const std::size_t space = authorization.find(' ');
  if (space == std::string_view::npos || lower(std::string(authorization.substr(0, space))) != "bearer")
    return std::nullopt;
  std::string_view token = authorization.substr(space);
  while (!token.empty() && token.front() == ' ') token.remove_prefix(1);
  while (!token.empty() && token.back() == ' ') token.remove_suffix(1);
  if (token.empty()) return std::nullopt;
  const Digest presented = sha256(token);
  const Entry* found = nullptr;
  for (const Entry& e : clients_) {
    unsigned char diff = 0;
    for (std::size_t i = 0; i < presented.size(); ++i) diff |= static_cast<unsigned char>(presented[i] ^ e.digest[i]);
    if (diff == 0 && !found) found = &e;
  }
  if (!found) return std::nullopt;
  return found->client;
}

bool role_allows(ClientRole role, const std::string& method, const std::string& path) {
  if (role == ClientRole::kOperator) return true;
  if (method == "GET" || method == "HEAD") return true;
  if (role == ClientRole::kReader) return false;
  // A device: start sessions, drive them, localise.
  if (method != "POST") return false;
  static const std::regex device_posts(R"(/v1/sessions|/v1/sessions/\d+/(frames|imu|finish)|/v1/localize)");
  return std::regex_match(path, device_posts);
}

}  // namespace orbatlas
