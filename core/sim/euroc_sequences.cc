#include "core/sim/euroc_sequences.h"

#include <algorithm>
#include <cctype>

#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/common/text_file.h"
#include "core/io/tum_trajectory.h"

namespace orbatlas::sim {
namespace {

struct Entry {
  const char* name;
  const char* gt_file;
  const char* ts_file;
  bool machine_hall;
};

constexpr Entry kSequences[] = {
    {"MH_01", "MH_01_easy.txt.gz", "MH01.txt", true},      {"MH_02", "MH_02_easy.txt.gz", "MH02.txt", true},
    {"MH_03", "MH_03_medium.txt.gz", "MH03.txt", true},    {"MH_04", "MH_04_difficult.txt.gz", "MH04.txt", true},
    {"MH_05", "MH_05_difficult.txt.gz", "MH05.txt", true}, {"V1_01", "V1_01_easy.txt.gz", "V101.txt", false},
};

std::string normalise(const std::string& name) {
  std::string out;
  for (const char c : name)
    if (std::isalnum(static_cast<unsigned char>(c)) != 0)
      out.push_back(static_cast<char>(std::toupper(static_cast<unsigned char>(c))));
  return out.substr(0, 4);  // "MH01", "V101"
}

}  // namespace

SequenceInfo find_sequence(const std::string& name) {
  const std::string key = normalise(name);
  for (const Entry& e : kSequences) {
    if (normalise(e.name) == key) {
      const auto dir = shipped_data_dir() / "euroc";
      return SequenceInfo{e.name, dir / "groundtruth" / e.gt_file, dir / "timestamps" / e.ts_file, e.machine_hall};
    }
  }
  std::string known;
  for (const Entry& e : kSequences) known += std::string(known.empty() ? "" : ", ") + e.name;
  throw Error("unknown sequence '" + name + "' (known: " + known + ")");
}

std::vector<std::string> machine_hall_sequence_names() {
  std::vector<std::string> names;
  for (const Entry& e : kSequences)
    if (e.machine_hall) names.emplace_back(e.name);
  return names;
}

Trajectory load_ground_truth(const SequenceInfo& sequence) { return read_tum_trajectory(sequence.ground_truth); }

std::vector<TimestampNs> load_camera_timestamps(const SequenceInfo& sequence) {
  std::vector<TimestampNs> out;
  for_each_line(sequence.camera_timestamps, [&](const TextLine& line) {
    const auto text = trim(line.text);
    if (text.empty() || text[0] == '#') return;
    const TimestampNs t = parse_int64(text, sequence.camera_timestamps, line.number);
    if (!out.empty() && t <= out.back())
      throw DataError(sequence.camera_timestamps.string() + ":" + std::to_string(line.number) +
                      ": camera timestamps not strictly increasing");
    out.push_back(t);
  });
  return out;
}

}  // namespace orbatlas::sim
