# Finds every third-party dependency once, as imported targets.
find_package(PkgConfig REQUIRED)
find_package(Threads REQUIRED)
find_package(OpenMP REQUIRED COMPONENTS CXX)
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(OpenCV 4 REQUIRED COMPONENTS core imgproc imgcodecs features2d calib3d video videoio objdetect aruco stitching)
find_package(yaml-cpp REQUIRED)
find_package(glog REQUIRED)
find_package(Ceres REQUIRED)

# LCM 1.3.1 in Debian ships no CMake package: use pkg-config (needs glib's dev package).
pkg_check_modules(LCM REQUIRED IMPORTED_TARGET lcm)
find_program(LCM_GEN lcm-gen REQUIRED)
find_file(LCM_JAR lcm.jar PATHS /usr/share/java REQUIRED)
find_file(JCHART2D_JAR jchart2d.jar PATHS /usr/share/java)
find_package(Java 11 COMPONENTS Development)

# ZeroMQ (vloc_lcm_tunnel): libzmq via pkg-config, cppzmq's header-only zmq.hpp.
pkg_check_modules(ZMQ REQUIRED IMPORTED_TARGET libzmq)
find_path(CPPZMQ_INCLUDE_DIR zmq.hpp REQUIRED)

# UAV stills: EXIF/XMP geotags (exiv2) and GIS products (GDAL).
pkg_check_modules(EXIV2 REQUIRED IMPORTED_TARGET exiv2)
find_package(GDAL REQUIRED)

# MRPT: only the modules the pose graph needs.
find_package(mrpt-graphslam REQUIRED)
find_package(mrpt-graphs REQUIRED)
find_package(mrpt-poses REQUIRED)

if(VLOC_BUILD_TESTS)
  find_package(GTest REQUIRED)
endif()
if(VLOC_BUILD_BENCHMARKS)
  find_package(benchmark REQUIRED)
endif()
