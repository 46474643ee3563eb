# Per-layer include roots: a target sees only the headers of its own layer and, through its
# PUBLIC links, of the layers below it (core <- mesh <- {fluid, solid} <- coupling <- tools),
# so a lower layer cannot even find a higher one's headers. Includes keep their form,
# `#include "core/types.hpp"`.
#
# tetfsi_include_root(<target> <folder> [PUBLIC|PRIVATE]) makes
#   ${PROJECT_BINARY_DIR}/include/<folder>/<folder>  a symbolic link to  ${PROJECT_SOURCE_DIR}/<folder>
# and adds ${PROJECT_BINARY_DIR}/include/<folder> to <target>'s include directories (PUBLIC
# unless told otherwise). The link is made at configure time.
function(tetfsi_include_root target folder)
  set(scope PUBLIC)
  if(ARGC GREATER 2)
    set(scope ${ARGV2})
  endif()
  set(root ${PROJECT_BINARY_DIR}/include/${folder})
  set(source ${PROJECT_SOURCE_DIR}/${folder})
  if(NOT IS_DIRECTORY ${source})
    message(FATAL_ERROR "tetfsi_include_root: ${source} is not a folder")
  endif()
  file(MAKE_DIRECTORY ${root})
  if(IS_SYMLINK ${root}/${folder})
    file(READ_SYMLINK ${root}/${folder} current)
  else()
    set(current "")
  endif()
  if(NOT current STREQUAL source)
    file(REMOVE ${root}/${folder})
    file(CREATE_LINK ${source} ${root}/${folder} SYMBOLIC)
  endif()
  target_include_directories(${target} ${scope} ${root})
endfunction()
