# The firmware's cell configuration from a BPX file, at build time (CMake BMS_CELL_FILE; no
# fitted numbers committed as C++): runs `bmssim cell-config --cell FILE` (the header, the
# design-time bias from the cell's nominal DFN) and writes OUT_DIR/bms/fw/cells/file_cell.hpp (a firmware cell header
# like the committed ones, so the core includes it by its bms/fw path), which
# includes that header and names its traits cells::FileCellTraits and the cell FileCellName
# (bms/fw/config/cell_choice.hpp, BMS_CELL_ID 4).
#   cmake -DBMSSIM=path/to/bmssim -DCELL_FILE=cell.bpx.json -DOUT_DIR=dir -P cell_file.cmake
foreach(var BMSSIM CELL_FILE OUT_DIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "cell_file.cmake: -D${var}=... missing")
  endif()
endforeach()
if(NOT EXISTS "${CELL_FILE}")
  message(FATAL_ERROR "BMS_CELL_FILE=${CELL_FILE}: no such file")
endif()
set(work "${OUT_DIR}/cell-config")
file(REMOVE_RECURSE "${work}")
execute_process(COMMAND "${BMSSIM}" cell-config --cell "${CELL_FILE}" --out "${work}" --quiet
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "bmssim cell-config --cell ${CELL_FILE} failed (${rc}): ${err}")
endif()
file(READ "${work}/summary.json" summary)
string(JSON header GET "${summary}" header)
string(JSON traits GET "${summary}" traits)
string(JSON name GET "${summary}" cell)
string(JSON crc GET "${summary}" record_crc32)
string(JSON bias GET "${summary}" model_bias_ohm)
file(MAKE_DIRECTORY "${OUT_DIR}/bms/fw/cells")
file(WRITE "${OUT_DIR}/bms/fw/cells/file_cell.hpp.tmp"
"#pragma once
// Written by target/tools/cell_file.cmake from ${CELL_FILE}: `bmssim cell-config` (${header},
// record CRC-32 ${crc}, design-time bias ${bias} ohm). Do not edit; the build regenerates it.
#include \"cell-config/${header}\"

namespace bms::fw {
namespace cells {
using FileCellTraits = ${traits};
}  // namespace cells
struct FileCellName {
  static constexpr const char* kValue = \"${name}\";
};
}  // namespace bms::fw
")
file(RENAME "${OUT_DIR}/bms/fw/cells/file_cell.hpp.tmp" "${OUT_DIR}/bms/fw/cells/file_cell.hpp")
