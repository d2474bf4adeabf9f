#pragma once
// The server's TLS (OpenSSL): its certificate chain and private key, loaded once
// and shared by every connection (`orbatlas-server --tls-cert/--tls-key`).
// TLS 1.2 at least; OpenSSL's default cipher suites.
#include <filesystem>
#include <memory>

struct ssl_ctx_st;

namespace orbatlas {

class TlsContext {
 public:
  // Throws Error naming the file when the certificate or key cannot be read,
  // or when they do not belong together.
  TlsContext(const std::filesystem::path& certificate_chain, const std::filesystem::path& private_key);
  ~TlsContext();
  TlsContext(const TlsContext&) = delete;
  TlsContext& operator=(const TlsContext&) = delete;

  ssl_ctx_st* native() const { return ctx_; }

 private:
  ssl_ctx_st* ctx_ = nullptr;
};

}  // namespace orbatlas
