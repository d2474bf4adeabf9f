// The vocabulary file (docs/vocabulary.md): a Cereal binary archive of a header,
// the content hash, and flat node and word arrays. Everything after the hash is
// the "body"; the hash is 64-bit FNV-1a over the body's bytes, checked on load.
#include <bit>
#include <cstring>
#include <fstream>
#include <sstream>
#include <streambuf>

#include <cereal/archives/binary.hpp>

#include "core/common/error.h"
#include "core/vocabulary/vocabulary_impl.h"

namespace orbatlas {
namespace {

using vocabulary_detail::VocabularyTree;

static_assert(std::endian::native == std::endian::little, "the vocabulary file is little-endian");
static_assert(sizeof(Descriptor) == 32);

constexpr std::string_view kMagic = "ORBATLAS-VOCAB";
constexpr std::uint32_t kFormatVersion = 1;
constexpr std::size_t kMaxStringLength = 64;
constexpr std::size_t kHashLength = 16;
// Bytes before the body: magic (u64 length + 14 chars), version (u32), hash (u64 length + 16 chars).
constexpr std::size_t kBodyOffset = 8 + kMagic.size() + 4 + 8 + kHashLength;

template <class Archive>
void write_string(Archive& ar, std::string_view s) {  // Cereal's own std::string layout
  ar(static_cast<std::uint64_t>(s.size()));
  ar(cereal::binary_data(s.data(), s.size()));
}

template <class T>
void write_array(cereal::BinaryOutputArchive& ar, const std::vector<T>& v) {
  ar(cereal::binary_data(v.data(), v.size() * sizeof(T)));
}

// Reads an in-memory file through Cereal and knows how far it got.
class MemoryReader : public std::streambuf {
 public:
  explicit MemoryReader(std::string& bytes) { setg(bytes.data(), bytes.data(), bytes.data() + bytes.size()); }
  std::size_t position() const { return static_cast<std::size_t>(gptr() - eback()); }
  std::size_t remaining() const { return static_cast<std::size_t>(egptr() - gptr()); }
};

class BodyDecoder {
 public:
  BodyDecoder(cereal::BinaryInputArchive& ar, const MemoryReader& reader, const std::string& file)
      : ar_(ar), reader_(reader), file_(file) {}

  std::string read_string(const char* what) {
    std::uint64_t length = 0;
    ar_(length);
    if (length > kMaxStringLength)
      fail(std::string("corrupt ") + what + " field (length " + std::to_string(length) + ")");
    std::string s(length, '\0');
    ar_(cereal::binary_data(s.data(), s.size()));
    return s;
  }
  template <class T>
  void read_array(std::vector<T>& v, std::uint64_t count, const char* what) {
    if (count > reader_.remaining() / sizeof(T))
      fail(std::string("truncated or corrupt: the header announces ") + std::to_string(count) + " " + what +
           " but only " + std::to_string(reader_.remaining()) + " bytes remain");
    v.resize(count);
    ar_(cereal::binary_data(v.data(), v.size() * sizeof(T)));
  }
  [[noreturn]] void fail(const std::string& message) const { throw DataError(file_ + ": " + message); }

 private:
  cereal::BinaryInputArchive& ar_;
  const MemoryReader& reader_;
  const std::string& file_;
};

std::string read_file_bytes(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw DataError(path.string() + ": cannot open vocabulary file (" +
                    (std::filesystem::exists(path, ec) ? "not a regular file" : "no such file") + ")");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw DataError(path.string() + ": cannot open vocabulary file");
  std::string bytes(static_cast<std::size_t>(std::filesystem::file_size(path, ec)), '\0');
  if (ec) throw DataError(path.string() + ": cannot read the file size");
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (static_cast<std::size_t>(in.gcount()) != bytes.size()) throw DataError(path.string() + ": read error");
  return bytes;
}

}  // namespace

namespace vocabulary_detail {

std::string encode_body(const VocabularyTree& tree, const VocabularyInfo& info) {
  std::ostringstream out(std::ios::binary);
  {
    cereal::BinaryOutputArchive ar(out);
    ar(static_cast<std::int32_t>(tree.k), static_cast<std::int32_t>(tree.levels));
    write_string(ar, info.weighting);
    write_string(ar, info.scoring);
    write_string(ar, info.descriptor);
    ar(static_cast<std::uint64_t>(info.training_images), static_cast<std::uint64_t>(info.training_descriptors),
       static_cast<std::uint64_t>(tree.node_count()), static_cast<std::uint64_t>(tree.word_nodes.size()));
    write_array(ar, tree.descriptors);
    write_array(ar, tree.first_child);
    write_array(ar, tree.child_count);
    write_array(ar, tree.word_nodes);
    write_array(ar, tree.word_weights);
  }
  return std::move(out).str();
}

std::string content_hash(std::string_view body) {
  std::uint64_t h = 0xcbf29ce484222325ull;  // FNV-1a 64 offset basis
  for (const char c : body) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ull;  // FNV-1a 64 prime
  }
  static constexpr char kHex[] = "0123456789abcdef";
  std::string hex(kHashLength, '0');
  for (std::size_t i = 0; i < kHashLength; ++i) hex[kHashLength - 1 - i] = kHex[(h >> (4 * i)) & 0xF];
  return hex;
}

}  // namespace vocabulary_detail

void Vocabulary::save(const std::filesystem::path& path) const {
  const std::string body = vocabulary_detail::encode_body(impl_->tree, impl_->info);
  const std::string hash = vocabulary_detail::content_hash(body);
  std::ostringstream head(std::ios::binary);
  {
    cereal::BinaryOutputArchive ar(head);
    write_string(ar, kMagic);
    ar(kFormatVersion);
    write_string(ar, hash);
  }
  // Written next to the target and renamed, so a failed save leaves no half file.
  std::filesystem::path tmp = path;
  tmp += ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    ORBATLAS_CHECK(out, "cannot write vocabulary file " << tmp.string());
    const std::string h = std::move(head).str();
    out.write(h.data(), static_cast<std::streamsize>(h.size()));
    out.write(body.data(), static_cast<std::streamsize>(body.size()));
    out.close();
    ORBATLAS_CHECK(out, "error writing vocabulary file " << tmp.string());
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw_error("cannot write vocabulary file " + path.string());
  }
}

Vocabulary Vocabulary::load(const std::filesystem::path& path) {
  const std::string file = path.string();
  std::string bytes = read_file_bytes(path);
  MemoryReader reader(bytes);
  std::istream in(&reader);
  cereal::BinaryInputArchive ar(in);
  BodyDecoder decoder(ar, reader, file);

  // Magic, compared as raw bytes so that any foreign file gets the same message.
  std::string expected_head;
  {
    std::ostringstream out(std::ios::binary);
    cereal::BinaryOutputArchive magic_ar(out);
    write_string(magic_ar, kMagic);
    expected_head = std::move(out).str();
  }
  if (bytes.size() < expected_head.size() || std::memcmp(bytes.data(), expected_head.data(), expected_head.size()) != 0)
    decoder.fail("not an orbatlas vocabulary file (wrong magic; expected \"" + std::string(kMagic) + "\")");

  Vocabulary vocabulary;
  VocabularyTree& tree = vocabulary.impl_->tree;
  VocabularyInfo& info = vocabulary.impl_->info;
  std::string stored_hash;
  try {
    decoder.read_string("magic");  // already compared
    std::uint32_t version = 0;
    ar(version);
    if (version != kFormatVersion)
      decoder.fail("unsupported vocabulary format version " + std::to_string(version) + " (this build reads version " +
                   std::to_string(kFormatVersion) + ")");
    stored_hash = decoder.read_string("hash");
    if (stored_hash.size() != kHashLength) decoder.fail("corrupt hash field");
    std::int32_t k = 0, levels = 0;
    ar(k, levels);
    tree.k = k;
    tree.levels = levels;
    info.weighting = decoder.read_string("weighting");
    info.scoring = decoder.read_string("scoring");
    info.descriptor = decoder.read_string("descriptor");
    std::uint64_t images = 0, descriptors = 0, nodes = 0, words = 0;
    ar(images, descriptors, nodes, words);
    info.training_images = images;
    info.training_descriptors = descriptors;
    decoder.read_array(tree.descriptors, nodes, "nodes");
    decoder.read_array(tree.first_child, nodes, "nodes");
    decoder.read_array(tree.child_count, nodes, "nodes");
    decoder.read_array(tree.word_nodes, words, "words");
    decoder.read_array(tree.word_weights, words, "words");
  } catch (const cereal::Exception&) {
    decoder.fail("truncated vocabulary file (unexpected end after " + std::to_string(reader.position()) + " of " +
                 std::to_string(bytes.size()) + " bytes)");
  }
  if (reader.remaining() != 0)
    decoder.fail(std::to_string(reader.remaining()) + " unexpected bytes after the vocabulary");

  const std::string computed = vocabulary_detail::content_hash(std::string_view(bytes).substr(kBodyOffset));
  if (computed != stored_hash)
    decoder.fail("content hash mismatch (stored " + stored_hash + ", computed " + computed + "): the file is corrupt");
  if (info.weighting != "tf-idf")
    decoder.fail("unsupported weighting \"" + info.weighting + "\" (this build has tf-idf)");
  if (info.scoring != "l1") decoder.fail("unsupported scoring \"" + info.scoring + "\" (this build has l1)");
  if (info.descriptor != "orb-256")
    decoder.fail("unsupported descriptor \"" + info.descriptor + "\" (this build has orb-256)");
  try {
    tree.derive_and_check();
  } catch (const Error& e) {
    decoder.fail(std::string("invalid vocabulary tree: ") + e.what());
  }
  info.k = tree.k;
  info.levels = tree.levels;
  info.words = tree.word_nodes.size();
  info.nodes = tree.node_count();
  info.hash = stored_hash;
  return vocabulary;
}

}  // namespace orbatlas
