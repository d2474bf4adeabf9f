#include "server/http/tls_context.h"

#include <openssl/err.h>
#include <openssl/ssl.h>

#include <string>

#include "core/common/error.h"

namespace orbatlas {
namespace {

std::string openssl_errors() {
  std::string out;
  while (const unsigned long e = ERR_get_error()) {
    char text[256];
    ERR_error_string_n(e, text, sizeof text);
    out += (out.empty() ? "" : "; ") + std::string(text);
  }
  return out.empty() ? "no detail" : out;
}

}  // namespace

TlsContext::TlsContext(const std::filesystem::path& certificate_chain, const std::filesystem::path& private_key)
    : ctx_(SSL_CTX_new(TLS_server_method())) {
  if (!ctx_) throw Error("TLS: cannot create a context: " + openssl_errors());
  SSL_CTX_set_min_proto_version(ctx_, TLS1_2_VERSION);
  SSL_CTX_set_mode(ctx_, SSL_MODE_ACCEPT_MOVING_WRITE_BUFFER);
  const auto fail = [&](const std::string& what) {
    const std::string detail = openssl_errors();
    SSL_CTX_free(ctx_);
    ctx_ = nullptr;
    throw Error("TLS: " + what + ": " + detail);
  };
  if (SSL_CTX_use_certificate_chain_file(ctx_, certificate_chain.c_str()) != 1)
    fail("cannot read the certificate chain " + certificate_chain.string());
  if (SSL_CTX_use_PrivateKey_file(ctx_, private_key.c_str(), SSL_FILETYPE_PEM) != 1)
    fail("cannot read the private key " + private_key.string());
  if (SSL_CTX_check_private_key(ctx_) != 1)
    fail("the private key " + private_key.string() + " does not belong to the certificate " +
         certificate_chain.string());
}

TlsContext::~TlsContext() {
  if (ctx_) SSL_CTX_free(ctx_);
}

}  // namespace orbatlas
