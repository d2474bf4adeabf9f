#include "core/sim/recorded_imu.h"

#include "core/common/data_paths.h"
#include "core/common/error.h"
#include "core/common/text_file.h"

namespace orbatlas::sim {

std::filesystem::path recorded_imu_path(const std::string& sequence) {
  const auto dir = shipped_data_dir() / "euroc" / "imu";
  if (sequence == "MH_05") return dir / "MH_05_imu0.txt.gz";
  if (sequence == "MH_01") return dir / "MH_01_imu0_lossy.txt.gz";
  return {};
}

std::vector<ImuSample> load_recorded_imu(const std::string& sequence, TimestampNs first, TimestampNs last,
                                         TimestampNs offset) {
  const auto path = recorded_imu_path(sequence);
  ORBATLAS_CHECK(!path.empty(), "no IMU recording is shipped for " << sequence);
  std::vector<ImuSample> out;
  for_each_line(path, [&](const TextLine& line) {
    const auto text = trim(line.text);
    if (text.empty() || text[0] == '#') return;
    const auto f = split_fields(text, " ,\t", true);
    if (f.size() != 7) throw DataError(path.string() + ":" + std::to_string(line.number) + ": expected 7 columns");
    ImuSample s;
    s.t_ns = parse_int64(f[0], path, line.number) + offset;
    if (s.t_ns < first || s.t_ns > last) return;
    s.gyro = {parse_double(f[1], path, line.number), parse_double(f[2], path, line.number),
              parse_double(f[3], path, line.number)};
    s.accel = {parse_double(f[4], path, line.number), parse_double(f[5], path, line.number),
               parse_double(f[6], path, line.number)};
    out.push_back(s);
  });
  return out;
}

}  // namespace orbatlas::sim
