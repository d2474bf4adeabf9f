#pragma once
// An uploaded recording, once extracted (core/server/upload_jobs): where it is
// in the upload's folder, and its frames, ground truth and IMU for a session of
// a given sensor. Every list it holds may name files inside the upload only
// (core/io/recording_paths.h): an upload never reads another's files or the server's.
#include <filesystem>
#include <optional>
#include <vector>

#include "core/geometry/pose.h"
#include "core/io/euroc_reader.h"
#include "core/io/settings.h"

namespace orbatlas {

// The recording's folder: the upload's root or its only top-level folder,
// holding an EuRoC ASL recording (mav0/), a TUM RGB-D one (rgb.txt) or a
// KITTI odometry sequence (image_0/, times.txt, calib.txt). DataError otherwise.
std::filesystem::path uploaded_recording_root(const std::filesystem::path& extracted);

// Reads what the upload holds far enough to refuse bad lists (a name leaving
// the upload, a malformed line) before a job is made; nothing when it holds no
// recording at all (the job says so).
void check_uploaded_recording(const std::filesystem::path& extracted);

struct UploadedRecording {
  std::vector<DatasetFrame> frames;
  std::vector<GroundTruthState> ground_truth;
  std::vector<ImuSample> imu;
  // A single camera's: the camera in the body (its poses are the camera's,
  // at its map's scale: scored with a similarity against the camera's truth).
  std::optional<Pose3> T_b_c0;
};

// The frames of the recording at `root` for a session of `sensor`: stereo pairs
// of an ASL folder or a KITTI sequence (the left images for a single camera),
// or each colour image with its depth image of a TUM RGB-D one (`rgbd`); the
// ground truth and the IMU it holds. DataError for what does not fit.
UploadedRecording read_uploaded_recording(const std::filesystem::path& root, SensorType sensor);

}  // namespace orbatlas
