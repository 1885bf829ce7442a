# Per-target compile settings shared by every linksight target.
function(linksight_target_settings target)
  target_compile_features(${target} PUBLIC cxx_std_20)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
  if(CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
    target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow)
    # No fused multiply-add contraction: the CPU back ends and the OpenCL kernels
    # (FP_CONTRACT OFF) must round every distance the same way, also under -march=native.
    target_compile_options(${target} PRIVATE -ffp-contract=off)
  endif()
endfunction()
