#pragma once
// Internal to the vocabulary library: what a Vocabulary holds, and the encoding of
// its file body (shared by training, which computes the hash, and the file I/O).
#include <string>
#include <string_view>

#include "core/vocabulary/vocabulary.h"
#include "core/vocabulary/vocabulary_tree.h"

namespace orbatlas {

struct Vocabulary::Impl {
  vocabulary_detail::VocabularyTree tree;
  VocabularyInfo info;
};

namespace vocabulary_detail {

// The file body: every field after the stored hash (docs/vocabulary.md).
std::string encode_body(const VocabularyTree& tree, const VocabularyInfo& info);
// 64-bit FNV-1a of the body as 16 lower-case hex digits.
std::string content_hash(std::string_view body);

}  // namespace vocabulary_detail
}  // namespace orbatlas
