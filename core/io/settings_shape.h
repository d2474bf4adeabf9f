#pragma once
// OpenCV's YAML reader (4.6, Debian 12) loops forever on some malformed text
// (found by fuzz_settings: "%YAML:1.0\n-----0\n-s--\ni" and "%YAML:1.\n C:A\n:A--\n0"
// never return), and a session's settings are a client's text. So the text is
// first checked against the shape settings have, line by line, and only text of
// that shape reaches OpenCV: comments; the "%YAML:1.0" directive and a "---";
// "Key: value" lines (a key of letters, digits, '_' and '.'; a value that is a
// number or word, a quoted string, "!!opencv-matrix", or a flow sequence of
// numbers "[...]", which may go on over lines); indented "key: value" lines only
// inside an !!opencv-matrix. Anything else is "malformed YAML" naming the line.
#include <string>
#include <string_view>

namespace orbatlas {

// DataError "<label>: malformed YAML: line N: why" for text of another shape.
void check_settings_shape(std::string_view text, const std::string& label);

}  // namespace orbatlas
