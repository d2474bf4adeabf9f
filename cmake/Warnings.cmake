# Warnings for our own targets only (not for third-party headers, which are SYSTEM).
# ORBATLAS_WERROR (the test command, and so CI, turns it on): they are errors, so a
# new warning fails the build instead of scrolling past.
option(ORBATLAS_WERROR "Treat the project's own compiler warnings as errors" OFF)
function(orbatlas_target_defaults target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow=local
                                           -Wnon-virtual-dtor -Wno-deprecated-enum-enum-conversion)
  if(ORBATLAS_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(ORBATLAS_SANITIZE STREQUAL "address")
    target_compile_options(${target} PUBLIC -fsanitize=address,undefined -fno-omit-frame-pointer)
    target_link_options(${target} PUBLIC -fsanitize=address,undefined)
  elseif(ORBATLAS_SANITIZE STREQUAL "thread")
    target_compile_options(${target} PUBLIC -fsanitize=thread -fno-omit-frame-pointer)
    target_link_options(${target} PUBLIC -fsanitize=thread)
  endif()
endfunction()
