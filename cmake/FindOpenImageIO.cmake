# Finds OpenImageIO through pkg-config: Debian 12's OpenImageIOConfig.cmake
# fails without openimageio-tools and opencv headers, which a build does not need.
# Defines OpenImageIO_FOUND and the target OpenImageIO::OpenImageIO.
find_package(PkgConfig QUIET)
if(PkgConfig_FOUND)
  pkg_check_modules(PC_OIIO QUIET IMPORTED_TARGET OpenImageIO)
endif()
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(OpenImageIO REQUIRED_VARS PC_OIIO_FOUND)
if(OpenImageIO_FOUND AND NOT TARGET OpenImageIO::OpenImageIO)
  add_library(OpenImageIO::OpenImageIO ALIAS PkgConfig::PC_OIIO)
endif()
