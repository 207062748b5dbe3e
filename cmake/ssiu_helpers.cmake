include(GoogleTest)

# One-line helpers for a stage library, a test and a benchmark (after COLMAP's COLMAP_ADD_LIBRARY).

# ssiu_add_library(NAME stage SOURCES a.cc b.cc DEPS ssiu_core ...)
function(ssiu_add_library)
  cmake_parse_arguments(A "" "NAME" "SOURCES;DEPS" ${ARGN})
  add_library(ssiu_${A_NAME} STATIC ${A_SOURCES})
  target_include_directories(ssiu_${A_NAME} PUBLIC ${CMAKE_SOURCE_DIR}/src)
  target_compile_options(ssiu_${A_NAME} PRIVATE ${SSIU_WARNINGS})
  target_link_libraries(ssiu_${A_NAME} PUBLIC ${A_DEPS})
  ssiu_unity(ssiu_${A_NAME} SSIU_UNITY_LIBS)
endfunction()

# ssiu_unity(target option): when `option` (SSIU_UNITY_LIBS for a stage library, SSIU_UNITY_TESTS for a test
# program) is on, the target's files compile in batches (8 a library, 32 a test program), one translation
# unit each (CMake's unity build): the headers they share (Eigen, GoogleTest, the standard library) are
# parsed, and their templates instantiated, once a batch instead of once a file. Names in a file's
# anonymous namespace must then be the file's own within the target; a file that cannot be batched stays
# out (ssiu_add_stage's NO_UNITY).
function(ssiu_unity target option)
  if(${option})
    # A test program in one batch: its files share more (GoogleTest, the helpers) than they hold of their
    # own (sim_test's 15 files: 73 s in one batch against 85 s in two).
    set(_n 8)
    if(option STREQUAL "SSIU_UNITY_TESTS")
      set(_n 32)
    endif()
    set_target_properties(${target} PROPERTIES UNITY_BUILD ON UNITY_BUILD_BATCH_SIZE ${_n})
  endif()
endfunction()

# ssiu_add_test(NAME detect_test SOURCES detect_test.cc DEPS ssiu_detect [LABELS long] [NO_UNITY])
# NO_UNITY: the program's files compile one at a time (their anonymous namespaces share names).
# Every GoogleTest test becomes its own ctest entry (listed at ctest time, so the program is not run
# at build time): `ctest -R Suite.Name` runs one, and ctest -j balances them across cores.
# COMPILE_OPTIONS: the program's own (e.g. -O0); it then precompiles the headers for itself instead of
# taking ssiu_test_pch's (tests/CMakeLists.txt), whose flags its own no longer match.
function(ssiu_add_test)
  cmake_parse_arguments(A "NO_UNITY" "NAME" "SOURCES;DEPS;LABELS;COMPILE_OPTIONS" ${ARGN})
  add_executable(${A_NAME} ${A_SOURCES})
  if(NOT A_NO_UNITY)
    ssiu_unity(${A_NAME} SSIU_UNITY_TESTS)
  endif()
  target_compile_options(${A_NAME} PRIVATE ${SSIU_WARNINGS} ${SSIU_TEST_OPT} ${A_COMPILE_OPTIONS})
  target_link_libraries(${A_NAME} PRIVATE ${A_DEPS} ssiu_testing GTest::gtest GTest::gmock GTest::gtest_main)
  if(SSIU_PCH AND A_COMPILE_OPTIONS)
    target_precompile_headers(${A_NAME} PRIVATE ${SSIU_TEST_PCH_HEADERS})
  elseif(SSIU_PCH)
    target_precompile_headers(${A_NAME} REUSE_FROM ssiu_test_pch)
  endif()
  add_dependencies(${A_NAME} ssiu_opencv)  # loaded on first use by the stubs (core/opencv_edge.h)
  # One label: `long` for the Monte-Carlo programs (kept out of CI by -LE long), else the program's
  # name (ctest -L core_test). The data paths are compiled into ssiu_testing (tests/CMakeLists.txt).
  if(A_LABELS)
    set(_label ${A_LABELS})
  else()
    set(_label ${A_NAME})
  endif()
  gtest_discover_tests(${A_NAME} DISCOVERY_MODE PRE_TEST DISCOVERY_TIMEOUT 60 PROPERTIES LABELS ${_label})
endfunction()

# ssiu_add_bench(NAME detect_bench SOURCES detect_bench.cc DEPS ssiu_detect)
function(ssiu_add_bench)
  cmake_parse_arguments(A "" "NAME" "SOURCES;DEPS" ${ARGN})
  add_executable(${A_NAME} ${A_SOURCES})
  target_compile_options(${A_NAME} PRIVATE ${SSIU_WARNINGS})
  target_link_libraries(${A_NAME} PRIVATE ${A_DEPS} benchmark::benchmark)
  add_dependencies(${A_NAME} ssiu_opencv)
endfunction()

# ssiu_add_stage(NAME stage DEPS lower stages/libraries [OPENCV_EDGE a.cc ...] [NO_UNITY b.cc ...]): the stage library
# from every .cc in its folder (so parallel work on one stage never edits this file); header-only until
# it has a .cc. OPENCV_EDGE files go to the module libssiu_opencv.so instead (core/opencv_edge.h), so
# that the stage library, and `ssiu`, do not link OpenCV.
function(ssiu_add_stage)
  cmake_parse_arguments(A "" "NAME" "DEPS;OPENCV_EDGE;NO_UNITY" ${ARGN})
  file(GLOB _src CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*.cc)
  foreach(f ${A_OPENCV_EDGE})
    list(REMOVE_ITEM _src ${CMAKE_CURRENT_SOURCE_DIR}/${f})
    set_property(GLOBAL APPEND PROPERTY SSIU_OPENCV_EDGE_SOURCES ${CMAKE_CURRENT_SOURCE_DIR}/${f})
  endforeach()
  if(_src)
    # The stubs that forward to the module stay objects of their own: the module links the stage library
    # too, and a batch holding a stub would be pulled in beside the module's real function (defined twice).
    # NO_UNITY: a file whose anonymous-namespace types are members of a class of the ssiu namespace (legal
    # only in the file's own translation unit).
    foreach(f opencv_calls.cc ${A_NO_UNITY})
      set_source_files_properties(${CMAKE_CURRENT_SOURCE_DIR}/${f} PROPERTIES SKIP_UNITY_BUILD_INCLUSION ON)
    endforeach()
    ssiu_add_library(NAME ${A_NAME} SOURCES ${_src} DEPS ${A_DEPS})
  else()
    add_library(ssiu_${A_NAME} INTERFACE)
    target_include_directories(ssiu_${A_NAME} INTERFACE ${CMAKE_SOURCE_DIR}/src)
    target_link_libraries(ssiu_${A_NAME} INTERFACE ${A_DEPS})
  endif()
endfunction()

# ssiu_add_stage_tests(stage): tests/<stage>/*_test.cc -> one program <stage>_test in the normal run;
# *_longtest.cc -> <stage>_longtest with label "long" (kept out of CI, run by hand or in benchmarks).
function(ssiu_add_stage_tests stage)
  file(GLOB _tests CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*_test.cc)
  file(GLOB _long CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*_longtest.cc)
  if(_tests)
    ssiu_add_test(NAME ${stage}_test SOURCES ${_tests} DEPS ssiu_${stage} ${ARGN})
  endif()
  if(_long AND SSIU_BUILD_LONGTESTS)
    ssiu_add_test(NAME ${stage}_longtest SOURCES ${_long} DEPS ssiu_${stage} ${ARGN} LABELS long)
  endif()
endfunction()
