// The real KITTI excerpt (../shared/data/kitti/excerpt_1) through the map
// server: streamed as a live session and uploaded as a recording, each with no
// config, so that the settings come from the sequence's calib.txt (the stream
// sends them as the session's settings text; the upload's job derives them
// from the extracted folder). Skips with the reason without the data, fails
// under ORBATLAS_REQUIRE=all (CI).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "client/api/dataset_streamer.h"
#include "client/api/server_client.h"
#include "core/common/data_paths.h"
#include "core/io/kitti_odometry.h"
#include "tests/support/requirement.h"
#include "tests/support/server_test_fixture.h"

namespace orbatlas {
namespace {

TEST(ServerKitti, TheRealExcerptStreamsAndUploadsWithTheSettingsOfItsCalibration) {
  const std::optional<std::filesystem::path> root = shared_kitti_dir();
  if (!root || !is_kitti_sequence(*root / "excerpt_1"))
    ORBATLAS_NEEDS("the real KITTI excerpt (../shared/data/kitti/excerpt_1 or ORBATLAS_SHARED_KITTI)");
  const std::filesystem::path excerpt = *root / "excerpt_1";
  test::TempDbPath db("kitti");
  test::TestServer server(test::server_options(db.path));
  ServerClient client(server.url());

  StreamOptions o;
  o.dataset = excerpt;  // no config: calib.txt's
  o.rate = 0.0;
  o.show_progress = false;
  const StreamReport streamed = stream_dataset(client, o);
  EXPECT_EQ(streamed.frames, 51u);
  EXPECT_EQ(streamed.tracked, 51u);
  ASSERT_TRUE(streamed.ate_rmse_m.has_value());
  const nlohmann::json session = client.get_json("/v1/sessions/" + std::to_string(streamed.session));
  EXPECT_EQ(session["sensor"], "stereo");
  EXPECT_EQ(session["name"], "excerpt_1");

  const std::uint64_t job = client.upload(excerpt, "", "uploaded excerpt");
  const nlohmann::json status = test::wait_for_job(client, job);
  ASSERT_EQ(status["state"], "done") << status.dump();
  EXPECT_EQ(status["frames_total"], 51);
  EXPECT_EQ(status["tracked"], 51);
  ASSERT_TRUE(status.contains("ate_rmse_m"));
  EXPECT_LT(*streamed.ate_rmse_m, 0.12);
  EXPECT_LT(status["ate_rmse_m"].get<double>(), 0.12);
}

}  // namespace
}  // namespace orbatlas
