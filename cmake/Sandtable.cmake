# One configure function for every target: same standard, same warnings.
function(sandtable_configure_target target)
  target_compile_features(${target} PUBLIC cxx_std_20)
  target_compile_options(${target} PRIVATE
    -Wall -Wextra -Wconversion -Wshadow -Wno-sign-conversion)
  if(SANDTABLE_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  target_compile_definitions(${target} PRIVATE
    SANDTABLE_VERSION="${PROJECT_VERSION}")
endfunction()

# Unit tests that sit beside a library: NAME_test from test/*.cpp.
function(sandtable_add_unit_tests lib)
  if(NOT SANDTABLE_TESTS)
    return()
  endif()
  file(GLOB srcs CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/test/*.cpp)
  if(NOT srcs)
    return()
  endif()
  add_executable(${lib}_test ${srcs})
  sandtable_configure_target(${lib}_test)
  target_link_libraries(${lib}_test PRIVATE ${lib} GTest::gtest GTest::gtest_main ${ARGN})
  target_compile_definitions(${lib}_test PRIVATE
    SANDTABLE_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  gtest_discover_tests(${lib}_test WORKING_DIRECTORY ${PROJECT_SOURCE_DIR}
    DISCOVERY_TIMEOUT 60)
endfunction()

# libFuzzer targets (clang only): tools/fuzz.sh configures a separate build
# with -DSANDTABLE_FUZZ=ON and builds the target sandtable_fuzzers, every
# target added here; fuzzers.txt in the build directory lists "NAME PATH".
option(SANDTABLE_FUZZ "Build the libFuzzer targets (needs clang)" OFF)
function(sandtable_add_fuzzer name source)
  if(NOT SANDTABLE_FUZZ OR NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    return()
  endif()
  add_executable(${name} ${source})
  target_link_libraries(${name} PRIVATE ${ARGN})
  target_compile_options(${name} PRIVATE -fsanitize=fuzzer,address)
  target_link_options(${name} PRIVATE -fsanitize=fuzzer,address)
  set_property(GLOBAL APPEND PROPERTY SANDTABLE_FUZZERS ${name})
endfunction()
