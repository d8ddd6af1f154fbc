# Compiles models/default.safetensors into the library (an assembler .incbin: no size limit
# of a generated C array, no compile time), exposed as ii_default_model_begin/_end.
set(DEFAULT_MODEL_FILE ${PROJECT_SOURCE_DIR}/models/default.safetensors)
if(EXISTS ${DEFAULT_MODEL_FILE})
  enable_language(ASM)
  set(DEFAULT_MODEL_ASM ${CMAKE_BINARY_DIR}/default_model.S)
  file(WRITE ${DEFAULT_MODEL_ASM}
    "  .section .rodata\n"
    "  .global ii_default_model_begin\n"
    "  .global ii_default_model_end\n"
    "  .balign 64\n"
    "ii_default_model_begin:\n"
    "  .incbin \"${DEFAULT_MODEL_FILE}\"\n"
    "ii_default_model_end:\n"
    "  .section .note.GNU-stack,\"\",@progbits\n")
  set_source_files_properties(${DEFAULT_MODEL_ASM} PROPERTIES OBJECT_DEPENDS ${DEFAULT_MODEL_FILE})
  target_sources(ii_model PRIVATE ${DEFAULT_MODEL_ASM})
  # Only the one source that references the symbols knows: the model appearing or going away
  # recompiles that file, not the library (and keeps the shared precompiled header valid).
  set_source_files_properties(${PROJECT_SOURCE_DIR}/src/model/default_model.cpp PROPERTIES
    COMPILE_DEFINITIONS INSTAINPAINT_DEFAULT_MODEL SKIP_PRECOMPILE_HEADERS ON)
  message(STATUS "Default model: embedded (${DEFAULT_MODEL_FILE})")
else()
  message(STATUS "Default model: none (models/default.safetensors absent)")
endif()
# Adding or removing the file changes the folder: configure again then.
if(EXISTS ${PROJECT_SOURCE_DIR}/models)
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/models)
endif()
