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
# OpenSSL (libssl-dev): the clients' token digests (SHA-256) and TLS; the same
# library Debian's cpp-httplib is built with.
find_package(OpenSSL 3 REQUIRED)
find_package(PkgConfig REQUIRED)
# Debian's cpp-httplib is a compiled library without a CMake config: pkg-config carries
# the SSL/zlib/brotli defines it was built with, which must match ours.
pkg_check_modules(HTTPLIB REQUIRED IMPORTED_TARGET cpp-httplib)
# PostgreSQL's client library (libpq-dev), for an atlas in PostgreSQL (issue 23).
pkg_check_modules(LIBPQ REQUIRED IMPORTED_TARGET libpq)
# ROS 1 bags (`--bag`, `orbatlas sim --bag`): Debian's rosbag_storage (librosbag-dev)
# reads and writes them, sensor_msgs (libsensor-msgs-dev) defines Image and Imu.
# Their pkg-config files name packages Debian ships without one (pluginlib), so
# the headers and libraries are found directly. Used by one C++17 translation
# unit only (core/io/rosbag_raw.cc).
find_path(ROSBAG_INCLUDE_DIR rosbag/bag.h REQUIRED)
find_path(ROSBAG_SENSOR_MSGS_INCLUDE_DIR sensor_msgs/Imu.h REQUIRED)
find_path(ROSBAG_PLUGINLIB_INCLUDE_DIR pluginlib/class_loader.hpp PATH_SUFFIXES pluginlib REQUIRED)
find_path(ROSBAG_CLASS_LOADER_INCLUDE_DIR class_loader/class_loader.hpp PATH_SUFFIXES class_loader REQUIRED)
find_path(ROSBAG_RCPPUTILS_INCLUDE_DIR rcpputils/shared_library.hpp PATH_SUFFIXES rcpputils REQUIRED)
find_path(ROSBAG_RCUTILS_INCLUDE_DIR rcutils/shared_library.h PATH_SUFFIXES rcutils REQUIRED)
find_path(ROSBAG_AMENT_INCLUDE_DIR ament_index_cpp/get_package_prefix.hpp PATH_SUFFIXES ament_index_cpp REQUIRED)
set(ROSBAG_LIBRARIES "")
foreach(lib rosbag_storage roscpp_serialization rostime cpp_common console_bridge class_loader boost_filesystem)
  find_library(ROSBAG_LIB_${lib} ${lib} REQUIRED)
  list(APPEND ROSBAG_LIBRARIES ${ROSBAG_LIB_${lib}})
endforeach()
