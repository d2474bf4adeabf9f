// Uploads of recorded sequences (docs/api.md, "Uploads"): a tar extracted
// while it arrives, checked before its bytes are read, then a job; and the jobs.
#include <filesystem>
#include <string>
#include <system_error>

#include "core/archive/tar_stream_extractor.h"
#include "core/server/atlas_service.h"
#include "core/server/upload_jobs.h"
#include "wire/service_json.h"
#include "server/http/http_router.h"  // last: it includes <httplib.h>

namespace orbatlas::http_detail {

void install_upload_routes(Router& router, AtlasService& service, UploadJobs* jobs, std::uint64_t max_bytes) {
  router.post_streaming("/v1/uploads", [&service, jobs, max_bytes, &context = router.context()](
                                           const Request& req, Response& res, const httplib::ContentReader& reader) {
    // A refusal comes before the body is read; what is left of it must not be
    // taken for the next request on this connection: the client closes it.
    res.set_header("Connection", "close");
    run_guarded(context, req, res, [&] {
      if (!jobs) throw ServiceError(ServiceErrorKind::kUnavailable, "unavailable", "this server takes no uploads");
      SessionRequest request;
      request.name = req.get_param_value("name");
      // No config: the recording's own (a KITTI sequence's calib.txt), else euroc/stereo (UploadJobs).
      request.settings.config = req.has_param("config") ? req.get_param_value("config") : "";
      if (req.has_param("sensor")) request.sensor = req.get_param_value("sensor");
      if (req.has_param("mode")) request.mode = req.get_param_value("mode");
      service.check_upload(request);  // before receiving gigabytes for nothing
      // Extracted while it arrives: no copy of the archive on disk. Its files may
      // not add up to more than the upload limit (sparse entries could).
      const std::filesystem::path folder = jobs->new_upload_folder();
      struct Discard {  // the extracted files, unless a job took them
        std::filesystem::path path;
        bool keep = false;
        ~Discard() {
          std::error_code ec;
          if (!keep) std::filesystem::remove_all(path, ec);
        }
      } discard{folder};
      TarLimits limits;
      limits.max_total_bytes = max_bytes;
      TarStreamExtractor extractor(folder, limits, "the upload");
      std::uint64_t bytes = 0;
      bool too_large = false;
      const bool complete = reader([&](const char* data, std::size_t n) {
        bytes += n;
        if (bytes > max_bytes) {
          too_large = true;
          return false;
        }
        return extractor.write(data, n);  // false once the archive proved bad
      });
      if (too_large) {
        extractor.cancel();
        throw ServiceError(ServiceErrorKind::kTooLarge, "too_large",
                           "uploads are limited to " + std::to_string(max_bytes) + " bytes");
      }
      if (bytes == 0) {
        extractor.cancel();
        throw_bad_request("the upload is empty: send a tar of an EuRoC ASL folder");
      }
      if (!complete && extractor.state() == TarStreamExtractor::State::kReading) {  // the client stopped
        extractor.cancel();
        throw_bad_request("the upload was cut short after " + std::to_string(bytes) + " bytes");
      }
      const TarExtractReport report = extractor.finish();  // a bad archive: DataError, 400
      UploadJobs::check_recording(folder);                 // files named outside it: DataError, 422
      const JobId id = jobs->submit(folder, request, report.archive_bytes);
      discard.keep = true;
      reply_json(res, {{"job", id}, {"status", to_json(jobs->job(id))}}, 202);
    });
  });
  router.get("/v1/jobs", ([jobs](const Request&, Response& res) {
               json list = json::array();
               if (jobs)
                 for (const StoredJob& job : jobs->jobs()) list.push_back(to_json(job));
               reply_json(res, {{"jobs", list}});
             }));
  router.get(R"(/v1/jobs/(\d+))", ([jobs](const Request& req, Response& res) {
               const JobId id = id_from(req, 1, "job");
               if (!jobs) throw_not_found("no job " + std::to_string(id));
               reply_json(res, to_json(jobs->job(id)));
             }));
}

}  // namespace orbatlas::http_detail
