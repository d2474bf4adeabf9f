# Every dependency is a Debian package; see docs/dependencies.md for why each is used.
find_package(Eigen3 3.4 REQUIRED NO_MODULE)
find_package(OpenCV 4 REQUIRED COMPONENTS core imgproc imgcodecs calib3d features2d)
find_package(Ceres REQUIRED)
find_package(SQLite3 REQUIRED)
find_package(cereal REQUIRED)
find_package(ZLIB REQUIRED)
find_package(Threads REQUIRED)
find_package(CLI11 REQUIRED)
find_package(nlohmann_json 3.10 REQUIRED)
find_package(opengv REQUIRED)  # P3P and pose refinement on bearing vectors (camera-model agnostic relocalisation)
find_package(LibArchive 3.6 REQUIRED)  # tar uploads: every dialect parsed by a maintained library
find_package(prometheus-cpp REQUIRED)  # /metrics: counters, gauges, histograms and the text format (core library only)
find_package(PkgConfig REQUIRED)
# Debian's cpp-httplib is a compiled library without a CMake config: pkg-config carries
# the SSL/zlib/brotli defines it was built with, which must match ours.
pkg_check_modules(HTTPLIB REQUIRED IMPORTED_TARGET cpp-httplib)
