# Blind identification on the board over streamed truths (target/m4f_blind_main.cpp,
# target/tools/m4f_blind.py; docs/results/target.md). Included twice by
# target/CMakeLists.txt: in the host block (the references) and at the end of the cross block.
set(bms_m4f_gen ${CMAKE_CURRENT_BINARY_DIR}/generated)
if(NOT CMAKE_CROSSCOMPILING)
  # The reference: the same source with the firmware in double (and in float, to separate the
  # board's libm from float itself).
  foreach(suffix "" _float)
    add_executable(bms_m4f_blind_host${suffix} m4f_blind_main.cpp platform_host.cpp)
    target_include_directories(bms_m4f_blind_host${suffix} PRIVATE ${bms_m4f_gen})
    target_link_libraries(bms_m4f_blind_host${suffix} PRIVATE bms_fw_tick_host${suffix} bms_hal_iface bms_warnings)
    add_dependencies(bms_m4f_blind_host${suffix} bms_fw_source_hash)
  endforeach()
  return()
endif()

bms_board_image(bms_m4f_blind m4f_blind_main.cpp platform_mps2.cpp)
target_include_directories(bms_m4f_blind PRIVATE ${bms_m4f_gen})
target_compile_definitions(bms_m4f_blind PRIVATE BMS_TARGET_BOARD="${BMS_QEMU_MACHINE}")
target_link_libraries(bms_m4f_blind PRIVATE bms_fw_tick bms_board_stdio bms_board_mps2 bms_warnings)
add_dependencies(bms_m4f_blind bms_fw_source_hash)

# One blind truth, the first BMS_M4F_BLIND_TEST_TICKS ticks of its first cycle (CC discharge,
# CV, rest, then the CC charge where the film is learned), on the board against the host's
# double build of the same source: fails when the film estimate differs by more than 0.5 %.
if(BMS_TARGET_SCALAR STREQUAL "float")
  set(BMS_M4F_BLIND_TEST_TICKS 0 CACHE STRING "Ticks of the m4f blind ctest (0: the whole first cycle)")
  # Every ctest below: one truth's first cycle on the board and in the host's double build.
  set(bms_m4f_blind_first_cycle
      ${BMS_PYTHON3} ${BMS_TARGET_TOOLS}/m4f_blind.py
      --bmssim ${BMS_HOST_BUILD_DIR}/host_sim/bmssim
      --host-exe ${BMS_HOST_BUILD_DIR}/target/bms_m4f_blind_host
      --image $<TARGET_FILE:bms_m4f_blind> --qemu ${BMS_QEMU_SYSTEM_ARM} --machine ${BMS_QEMU_MACHINE}
      --truths 1 --cycles 1 --max-ticks ${BMS_M4F_BLIND_TEST_TICKS})
  add_test(NAME target_m4f_blind_vs_host
    COMMAND ${bms_m4f_blind_first_cycle} --limit-pct 0.5
            --out ${CMAKE_CURRENT_BINARY_DIR}/results/m4f-blind-test)
  # The same comparison held to 0.001 %: the check must report the film's difference.
  add_test(NAME target_m4f_blind_detects_difference
    COMMAND ${bms_m4f_blind_first_cycle} --limit-pct 0.001
            --out ${CMAKE_CURRENT_BINARY_DIR}/results/m4f-blind-canary)
  set_tests_properties(target_m4f_blind_detects_difference PROPERTIES
    PASS_REGULAR_EXPRESSION "FAIL: film float vs double: median")
  # A temperature-varying truth (15 C ambient, self-heating, 0.1 K sensor noise): the measured
  # temperature (temperature_meas_k, BMSMEAS2) reaches the tick on the board as `bmssim estimate`
  # passes it; the host's double build must equal estimate's film at every tick, the board within
  # 0.5 % of it (film, capacity), its costliest tick within 300 000 instructions.
  set(bms_m4f_thermal_truth --temperature-k 288.15 --effect thermal=0.05 --noise-t-k 0.1)
  add_test(NAME target_m4f_blind_temperature_vs_host
    COMMAND ${bms_m4f_blind_first_cycle} --limit-pct 0.5 --tick-limit 300000
            ${bms_m4f_thermal_truth} --estimate-check
            --out ${CMAKE_CURRENT_BINARY_DIR}/results/m4f-blind-temperature)
  # The same truth with the temperature left out of the file (BMSMEAS1): the replay must no longer
  # equal estimate's, or the comparison above would not show that the temperature arrives.
  add_test(NAME target_m4f_blind_temperature_detects_missing
    COMMAND ${bms_m4f_blind_first_cycle} --limit-pct 0.5
            ${bms_m4f_thermal_truth} --estimate-check --no-temperature
            --out ${CMAKE_CURRENT_BINARY_DIR}/results/m4f-blind-temperature-missing)
  set_tests_properties(target_m4f_blind_temperature_detects_missing PROPERTIES
    PASS_REGULAR_EXPRESSION "FAIL: host double vs bmssim estimate: film identical in")
  set_tests_properties(target_m4f_blind_vs_host target_m4f_blind_detects_difference
    target_m4f_blind_temperature_vs_host target_m4f_blind_temperature_detects_missing PROPERTIES
    LABELS target TIMEOUT 600 RESOURCE_LOCK target_qemu_m4f_blind)
endif()
