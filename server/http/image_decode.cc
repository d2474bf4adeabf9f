#include "server/http/image_decode.h"

#include <cctype>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <zlib.h>

#include "core/common/error.h"
#include "core/io/settings.h"

namespace orbatlas {
namespace {

bool starts_with(std::string_view bytes, std::string_view magic) { return bytes.substr(0, magic.size()) == magic; }

std::uint32_t big_endian(std::string_view b, std::size_t at, int n) {
  std::uint32_t v = 0;
  for (int i = 0; i < n; ++i) v = (v << 8) | static_cast<unsigned char>(b[at + i]);
  return v;
}

std::int64_t little_endian_signed32(std::string_view b, std::size_t at) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(b[at + i]);
  return static_cast<std::int32_t>(v);
}

std::optional<cv::Size> checked(std::int64_t w, std::int64_t h) {
  if (w <= 0 || h <= 0 || w > (1 << 30) || h > (1 << 30)) return cv::Size(0, 0);  // declared, but nonsense
  return cv::Size(static_cast<int>(w), static_cast<int>(h));
}

// PNG: the IHDR chunk comes first (width, height big-endian at 16 and 20).
std::optional<cv::Size> png_size(std::string_view b) {
  if (b.size() < 24 || b.substr(12, 4) != "IHDR") return std::nullopt;
  return checked(big_endian(b, 16, 4), big_endian(b, 20, 4));
}

// JPEG: walk the marker segments to the first start-of-frame (SOF0..SOF15 but
// DHT C4, JPG C8, DAC CC), whose height and width follow the precision byte.
std::optional<cv::Size> jpeg_size(std::string_view b) {
  std::size_t at = 2;
  while (at + 4 <= b.size()) {
    if (static_cast<unsigned char>(b[at]) != 0xff) return std::nullopt;
    const auto marker = static_cast<unsigned char>(b[at + 1]);
    if (marker == 0xff) {  // fill byte
      ++at;
      continue;
    }
    if (marker == 0xd8 || (marker >= 0xd0 && marker <= 0xd7) || marker == 0x01) {  // no length
      at += 2;
      continue;
    }
    const std::uint32_t length = big_endian(b, at + 2, 2);
    if (length < 2) return std::nullopt;
    if (marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 && marker != 0xcc) {
      if (at + 9 > b.size()) return std::nullopt;
      return checked(big_endian(b, at + 7, 2), big_endian(b, at + 5, 2));
    }
    if (marker == 0xda || marker == 0xd9) return std::nullopt;  // scan data or the end before any frame header
    at += 2 + length;
  }
  return std::nullopt;
}

// Binary PGM: "P5", whitespace, width, height, maxval; '#' comments between.
std::optional<cv::Size> pgm_size(std::string_view b) {
  std::size_t at = 2;
  std::int64_t values[2] = {0, 0};
  for (std::int64_t& v : values) {
    while (at < b.size()) {
      if (b[at] == '#') {
        while (at < b.size() && b[at] != '\n') ++at;
      } else if (std::isspace(static_cast<unsigned char>(b[at]))) {
        ++at;
      } else {
        break;
      }
    }
    const std::size_t digits_start = at;
    while (at < b.size() && std::isdigit(static_cast<unsigned char>(b[at])) && at - digits_start < 11)
      v = v * 10 + (b[at++] - '0');
    if (at == digits_start || at >= b.size()) return std::nullopt;
  }
  return checked(values[0], values[1]);
}

// BMP: BITMAPINFOHEADER width and height (signed; negative height: top-down).
std::optional<cv::Size> bmp_size(std::string_view b) {
  if (b.size() < 26) return std::nullopt;
  const std::int64_t h = little_endian_signed32(b, 22);
  return checked(little_endian_signed32(b, 18), h < 0 ? -h : h);
}

// Whether a PNG's image data (its IDAT chunks, inflated) is no more than its
// declared size needs: rows of filter byte and pixels (Adam7 interlacing adds a
// filter byte per pass row). Inflates into a small scratch buffer, stopping as
// soon as the bound is passed: surplus data cannot cost more than the image.
bool png_data_within_size(std::string_view b, const cv::Size& size) {
  if (b.size() < 29) return true;  // too short to tell: the decoder refuses it
  const int depth = static_cast<unsigned char>(b[24]), colour = static_cast<unsigned char>(b[25]);
  const int channels = colour == 2 ? 3 : colour == 4 ? 2 : colour == 6 ? 4 : 1;
  const std::uint64_t row_bytes = (static_cast<std::uint64_t>(size.width) * channels * depth + 7) / 8;
  const std::uint64_t bound =
      static_cast<std::uint64_t>(size.height) * (row_bytes + 1) + 8 * static_cast<std::uint64_t>(size.height) + 64;
  z_stream z{};
  if (inflateInit(&z) != Z_OK) return true;
  unsigned char scratch[65536];
  std::uint64_t inflated = 0;
  bool within = true, ended = false;
  for (std::size_t at = 8; at + 12 <= b.size() && within && !ended;) {
    const std::uint32_t length = big_endian(b, at, 4);
    if (length > b.size() - at - 12) break;  // truncated: the decoder says so
    if (b.substr(at + 4, 4) == "IDAT") {
      z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(b.data() + at + 8));
      z.avail_in = length;
      while (z.avail_in > 0 && within) {
        z.next_out = scratch;
        z.avail_out = sizeof scratch;
        const int r = inflate(&z, Z_NO_FLUSH);
        inflated += sizeof scratch - z.avail_out;
        within = inflated <= bound;
        if (r == Z_STREAM_END) {
          // Compressed bytes after the stream's end are more data nobody asked for.
          within = within && z.avail_in == 0;
          ended = true;
          break;
        }
        if (r != Z_OK) break;  // corrupt: the decoder says so
      }
    }
    at += 12 + length;
  }
  inflateEnd(&z);
  return within;
}

}  // namespace

std::optional<cv::Size> encoded_image_size(std::string_view bytes) {
  if (starts_with(bytes, "\x89PNG\r\n\x1a\n")) return png_size(bytes);
  if (starts_with(bytes, "\xff\xd8\xff")) return jpeg_size(bytes);
  if (starts_with(bytes, "P5")) return pgm_size(bytes);
  if (starts_with(bytes, "BM")) return bmp_size(bytes);
  return std::nullopt;
}

cv::Mat decode_request_image(std::string_view bytes, const std::optional<RawImageSize>& raw, const std::string& what,
                             const std::optional<cv::Size>& expected) {
  ORBATLAS_DATA_CHECK(!bytes.empty(), what << " is empty");
  const auto size_text = [](const cv::Size& s) { return std::to_string(s.width) + "x" + std::to_string(s.height); };
  // Raw pixels when the size says so: their first bytes may look like a file signature.
  const bool raw_sized = raw && raw->width > 0 && raw->height > 0 &&
                         bytes.size() == static_cast<std::size_t>(raw->width) * static_cast<std::size_t>(raw->height);
  const bool encoded = starts_with(bytes, "\x89PNG\r\n\x1a\n") || starts_with(bytes, "\xff\xd8\xff") ||
                       starts_with(bytes, "P5") || starts_with(bytes, "BM");
  if (!raw_sized && encoded) {
    const std::optional<cv::Size> declared = encoded_image_size(bytes);
    ORBATLAS_DATA_CHECK(declared.has_value(), what << " is a corrupt or truncated image file (" << bytes.size()
                                                   << " bytes; no readable header)");
    // Each side, not the area: two sides of 2^30 overflow an int's area (found by fuzz_image_decode).
    ORBATLAS_DATA_CHECK(declared->width > 0 && declared->height > 0, what << " declares an impossible image size");
    if (expected) {
      ORBATLAS_DATA_CHECK(*declared == *expected, what << " is " << size_text(*declared) << "; the camera takes "
                                                       << size_text(*expected) << " (refused before decoding)");
    } else {
      ORBATLAS_DATA_CHECK(declared->width <= kMaxImageSide && declared->height <= kMaxImageSide,
                          what << " is " << size_text(*declared) << "; at most " << kMaxImageSide
                               << " pixels a side (refused before decoding)");
    }
    if (starts_with(bytes, "\x89PNG\r\n\x1a\n"))
      ORBATLAS_DATA_CHECK(png_data_within_size(bytes, *declared), what << " holds more image data than its "
                                                                       << size_text(*declared)
                                                                       << " pixels need (refused before decoding)");
    const cv::Mat buffer(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<char*>(bytes.data()));
    cv::Mat image;
    try {
      image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception&) {
      image.release();
    }
    ORBATLAS_DATA_CHECK(!image.empty(), what << " is a corrupt or truncated image file (" << bytes.size() << " bytes)");
    ORBATLAS_DATA_CHECK(image.size() == *declared, what << " decodes to " << size_text(image.size())
                                                        << " but its header says " << size_text(*declared));
    ORBATLAS_DATA_CHECK(image.depth() == CV_8U,
                        what << " must have 8-bit pixels (it has " << (image.elemSize1() * 8) << "-bit ones)");
    return image;
  }
  ORBATLAS_DATA_CHECK(raw.has_value(), what << " is not a PNG/JPEG/PGM/BMP file; raw 8-bit pixels need the fields "
                                               "'width' and 'height'");
  ORBATLAS_DATA_CHECK(
      raw->width > 0 && raw->height > 0 && raw->width <= kMaxImageSide && raw->height <= kMaxImageSide,
      what << ": width and height must be 1.." << kMaxImageSide << ", got " << raw->width << "x" << raw->height);
  const auto expected_bytes = static_cast<std::size_t>(raw->width) * static_cast<std::size_t>(raw->height);
  ORBATLAS_DATA_CHECK(bytes.size() == expected_bytes, what << " has " << bytes.size() << " bytes; " << raw->width << "x"
                                                           << raw->height << " raw 8-bit pixels are "
                                                           << expected_bytes);
  cv::Mat image(raw->height, raw->width, CV_8UC1);
  std::memcpy(image.data, bytes.data(), expected_bytes);
  return image;
}

cv::Mat decode_request_depth(std::string_view bytes, const std::string& what, const cv::Size& expected) {
  ORBATLAS_DATA_CHECK(!bytes.empty(), what << " is empty");
  ORBATLAS_DATA_CHECK(starts_with(bytes, "\x89PNG\r\n\x1a\n"), what << " must be a 16-bit PNG (TUM RGB-D's format)");
  const std::optional<cv::Size> declared = encoded_image_size(bytes);
  ORBATLAS_DATA_CHECK(declared.has_value(), what << " is a corrupt or truncated PNG (" << bytes.size() << " bytes)");
  ORBATLAS_DATA_CHECK(*declared == expected, what << " is " << declared->width << "x" << declared->height
                                                  << "; the camera takes " << expected.width << "x" << expected.height
                                                  << " (refused before decoding)");
  ORBATLAS_DATA_CHECK(png_data_within_size(bytes, *declared), what << " holds more image data than its "
                                                                   << declared->width << "x" << declared->height
                                                                   << " pixels need (refused before decoding)");
  const cv::Mat buffer(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<char*>(bytes.data()));
  cv::Mat depth;
  try {
    depth = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception&) {
    depth.release();
  }
  ORBATLAS_DATA_CHECK(!depth.empty() && depth.size() == expected,
                      what << " is a corrupt or truncated PNG (" << bytes.size() << " bytes)");
  ORBATLAS_DATA_CHECK(depth.type() == CV_16UC1, what << " must be 16-bit single-channel (it has " << depth.channels()
                                                     << " channel(s) of " << (depth.elemSize1() * 8) << " bits)");
  return depth;
}

}  // namespace orbatlas
