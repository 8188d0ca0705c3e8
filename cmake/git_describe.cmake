# Writes OUT (from IN) with GISSAR_GIT_DESCRIBE set to `git describe
# --always --dirty` of SOURCE_DIR ("unknown" without git or a .git): run at
# every build (util/CMakeLists.txt), so that every output's provenance names
# the commit the binary was built from, not the one it was configured at.
# configure_file leaves OUT untouched when the text is unchanged: only a new
# commit, or a clean tree turning dirty, recompiles what includes it.
set(GISSAR_GIT_DESCRIBE "unknown")
if(GIT_EXECUTABLE AND EXISTS "${SOURCE_DIR}/.git")
  execute_process(COMMAND "${GIT_EXECUTABLE}" describe --always --dirty
                  WORKING_DIRECTORY "${SOURCE_DIR}"
                  OUTPUT_VARIABLE describe OUTPUT_STRIP_TRAILING_WHITESPACE
                  RESULT_VARIABLE status ERROR_QUIET)
  if(status EQUAL 0 AND describe)
    set(GISSAR_GIT_DESCRIBE "${describe}")
  endif()
endif()
configure_file("${IN}" "${OUT}" @ONLY)
