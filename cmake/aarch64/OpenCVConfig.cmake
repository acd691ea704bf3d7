# OpenCV 4.6 from the arm64 sysroot of cmake/aarch64-linux-gnu.cmake: the variables
# find_package(OpenCV COMPONENTS ...) sets (OpenCV_INCLUDE_DIRS, OpenCV_LIBS), for the asked
# components only.
set(OpenCV_VERSION 4.6.0)
set(_occmap_root "${OCCMAP_AARCH64_SYSROOT}")
set(OpenCV_INCLUDE_DIRS "${_occmap_root}/usr/include/opencv4" "${_occmap_root}/usr/include/aarch64-linux-gnu/opencv4")
set(OpenCV_LIBS "")
foreach(_occmap_component ${OpenCV_FIND_COMPONENTS})
  set(_occmap_lib "${_occmap_root}/usr/lib/aarch64-linux-gnu/libopencv_${_occmap_component}.so")
  if(NOT EXISTS "${_occmap_lib}")
    set(OpenCV_FOUND FALSE)
    set(OpenCV_NOT_FOUND_MESSAGE "expected ${_occmap_lib} (libopencv-${_occmap_component}-dev:arm64 in the sysroot)")
    return()
  endif()
  list(APPEND OpenCV_LIBS "${_occmap_lib}")
endforeach()
set(OpenCV_FOUND TRUE)
