// libFuzzer: an upload's tar as it arrives (core/archive/tar_stream_extractor.h),
// extracted into a fresh folder each run with small limits, fed in pieces of
// the sizes the input's first byte picks. Nothing may land outside the folder.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

#include "core/archive/tar_stream_extractor.h"
#include "core/common/error.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::filesystem::path root =
      std::filesystem::temp_directory_path() / ("orbatlas_fuzz_tar_" + std::to_string(::getpid()));
  const std::filesystem::path dest = root / "upload";
  std::filesystem::remove_all(root);
  std::filesystem::create_directories(root);
  orbatlas::TarLimits limits;
  limits.max_total_bytes = 1 << 20;
  limits.max_file_bytes = 1 << 20;
  limits.max_entries = 64;
  const std::size_t piece = 1 + data[0] * 7;
  try {
    orbatlas::TarStreamExtractor extractor(dest, limits, "fuzz.tar");
    bool taking = true;
    for (std::size_t at = 1; at < size && taking; at += piece)
      taking = extractor.write(reinterpret_cast<const char*>(data) + at, std::min(piece, size - at));
    if (taking)
      extractor.finish();
    else
      extractor.cancel();
  } catch (const orbatlas::Error&) {
  }
  // Everything under root is the destination's.
  for (const auto& entry : std::filesystem::directory_iterator(root))
    if (entry.path() != dest) __builtin_trap();
  std::filesystem::remove_all(root);
  return 0;
}
