#include "io/file_hash.h"

#include <openssl/evp.h>

#include <fstream>
#include <memory>
#include <vector>

#include <fmt/format.h>

#include "common/error.h"

namespace ii {

namespace {

using DigestContext = std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)>;

DigestContext digest_context(const std::filesystem::path& path, const EVP_MD* md, const char* name) {
  DigestContext ctx(EVP_MD_CTX_new(), EVP_MD_CTX_free);
  if (!ctx || EVP_DigestInit_ex(ctx.get(), md, nullptr) != 1) fail_file(path, "{}: OpenSSL failed", name);
  return ctx;
}

std::string hex_digest(EVP_MD_CTX* ctx) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  EVP_DigestFinal_ex(ctx, digest, &length);
  std::string hex;
  for (unsigned int i = 0; i < length; ++i) hex += fmt::format("{:02x}", digest[i]);
  return hex;
}

// Reads the file once, feeding every context; the number of bytes read.
uintmax_t digest_file(const std::filesystem::path& path, std::initializer_list<EVP_MD_CTX*> contexts) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail_file(path, "cannot open for reading");
  std::vector<char> buffer(1 << 20);
  uintmax_t size = 0;
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    if (in.gcount() <= 0) continue;
    for (EVP_MD_CTX* ctx : contexts) EVP_DigestUpdate(ctx, buffer.data(), static_cast<size_t>(in.gcount()));
    size += static_cast<uintmax_t>(in.gcount());
  }
  if (in.bad()) fail_file(path, "read error");
  return size;
}

}  // namespace

FileDigests digests_of_file(const std::filesystem::path& path) {
  const DigestContext sha = digest_context(path, EVP_sha256(), "SHA-256");
  const DigestContext md5 = digest_context(path, EVP_md5(), "MD5");
  FileDigests out;
  out.size = digest_file(path, {sha.get(), md5.get()});
  out.sha256 = hex_digest(sha.get());
  out.md5 = hex_digest(md5.get());
  return out;
}

std::string sha256_of_file(const std::filesystem::path& path) {
  const DigestContext ctx = digest_context(path, EVP_sha256(), "SHA-256");
  digest_file(path, {ctx.get()});
  return hex_digest(ctx.get());
}

}  // namespace ii
