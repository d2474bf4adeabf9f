#include "wire/run_report_json.h"

#include "wire/stats_json.h"

namespace orbatlas {

nlohmann::json to_json(const DatasetRunReport& report) {
  nlohmann::json j = to_json(report.stats);
  j["skipped_frames"] = report.skipped_frames;
  j["late_frames"] = report.late_frames;
  j["peak_rss_mb"] = report.peak_rss_mb;
  j["wall_s"] = report.wall_s;
  if (!report.failed.empty()) j["failed"] = report.failed;
  if (report.ate_rmse_m) {
    j["ate_rmse_m"] = *report.ate_rmse_m;
    j["ate_align"] = report.ate_sim3 ? "sim3" : "se3";
  }
  // What track() returned, frame by frame (the final trajectory is corrected afterwards).
  j["live_poses"] = report.live_trajectory.size();
  j["live_fraction"] = report.stats.frames > 0 ? static_cast<double>(report.live_trajectory.size()) /
                                                     static_cast<double>(report.stats.frames)
                                               : 0.0;
  j["live_jumps_m"] = to_json_summary(report.live_jumps_m);
  if (report.live_ate_rmse_m) j["live_ate_rmse_m"] = *report.live_ate_rmse_m;
  if (report.session) j["session"] = *report.session;
  if (report.loaded_maps > 0 || report.session) {
    j["atlas"] = {{"loaded_maps", report.loaded_maps},
                  {"loaded_keyframes", report.loaded_keyframes},
                  {"load_s", report.atlas_load_s}};
  }
  if (report.black_out) {
    nlohmann::json b = {{"frames", report.black_out->frames}, {"by_imu", report.black_out->by_imu}};
    b["frames_to_visual"] =
        report.black_out->frames_to_visual ? nlohmann::json(*report.black_out->frames_to_visual) : nlohmann::json();
    b["error_at_end_m"] =
        report.black_out->error_at_end_m ? nlohmann::json(*report.black_out->error_at_end_m) : nlohmann::json();
    b["error_after_m"] =
        report.black_out->error_after_m ? nlohmann::json(*report.black_out->error_after_m) : nlohmann::json();
    j["black_out"] = b;
  }
  if (report.checkpoints) {
    nlohmann::json c = {{"checkpoints", report.checkpoints->checkpoints},
                        {"commits", report.checkpoints->commits},
                        {"failures", report.checkpoints->failures},
                        {"sequence", report.checkpoints->sequence},
                        {"wall_ms", to_json_summary(report.checkpoints->wall_ms)}};
    j["checkpoints"] = c;
  }
  return j;
}

}  // namespace orbatlas
