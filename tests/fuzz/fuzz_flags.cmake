# Included by the top-level CMakeLists.txt when FORESTMAP_FUZZ is ON, before any target exists:
# every library built here gets libFuzzer's coverage instrumentation plus AddressSanitizer and
# UndefinedBehaviorSanitizer (an undefined-behaviour report aborts, so libFuzzer sees a crash).
# The fuzz executables themselves add -fsanitize=fuzzer (libFuzzer's main) in tests/fuzz.
if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
  message(FATAL_ERROR "FORESTMAP_FUZZ needs clang: cmake -DCMAKE_C_COMPILER=clang "
                      "-DCMAKE_CXX_COMPILER=clang++ -DFORESTMAP_FUZZ=ON ...")
endif()
if(FORESTMAP_SANITIZE)
  message(FATAL_ERROR "FORESTMAP_FUZZ already builds with address and undefined sanitizers")
endif()
add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined
                    -fno-omit-frame-pointer -g)
add_link_options(-fsanitize=address,undefined)
