# The page of `instainpaint serve`: web/src bundled by esbuild (from web/node_modules, which
# `make deps` installs with `npm ci` from web/package-lock.json) and compiled into ii_web with
# .incbin, like the default model. Without node_modules the server still runs and its page
# says how to get the bundle.
set(WEB_DIR ${PROJECT_SOURCE_DIR}/web)
set(WEB_ESBUILD ${WEB_DIR}/node_modules/.bin/esbuild)
if(EXISTS ${WEB_ESBUILD})
  enable_language(ASM)
  set(WEB_BUNDLE ${CMAKE_BINARY_DIR}/web/app.js)
  file(GLOB WEB_SOURCES CONFIGURE_DEPENDS ${WEB_DIR}/src/*)
  # The bundle is also embedded gzipped (-9, once, here): the server would otherwise compress its
  # 3 MB at every page load, and with Brotli (what browsers ask for first) that took 5.7 s on 2 cores.
  add_custom_command(OUTPUT ${WEB_BUNDLE} ${WEB_BUNDLE}.gz
    COMMAND ${WEB_ESBUILD} ${WEB_DIR}/src/main.js --bundle --format=esm --minify --log-level=warning
            --outfile=${WEB_BUNDLE}
    COMMAND gzip -9 -n -k -f ${WEB_BUNDLE}
    DEPENDS ${WEB_SOURCES} ${WEB_DIR}/package-lock.json
    COMMENT "Bundling the web page (esbuild) and gzipping it" VERBATIM)
  set(WEB_ASM ${CMAKE_BINARY_DIR}/web_assets.S)
  file(WRITE ${WEB_ASM}
    "  .section .rodata\n"
    "  .global ii_web_index_begin\n  .global ii_web_index_end\n"
    "  .global ii_web_app_begin\n  .global ii_web_app_end\n"
    "  .global ii_web_app_gz_begin\n  .global ii_web_app_gz_end\n"
    "ii_web_index_begin:\n  .incbin \"${WEB_DIR}/src/index.html\"\nii_web_index_end:\n"
    "ii_web_app_begin:\n  .incbin \"${WEB_BUNDLE}\"\nii_web_app_end:\n"
    "ii_web_app_gz_begin:\n  .incbin \"${WEB_BUNDLE}.gz\"\nii_web_app_gz_end:\n"
    "  .section .note.GNU-stack,\"\",@progbits\n")
  set_source_files_properties(${WEB_ASM} PROPERTIES OBJECT_DEPENDS "${WEB_BUNDLE};${WEB_BUNDLE}.gz;${WEB_DIR}/src/index.html")
  # The bundle as a source too, so that the target runs its custom command.
  target_sources(ii_web PRIVATE ${WEB_ASM} ${WEB_BUNDLE})
  set_source_files_properties(${PROJECT_SOURCE_DIR}/src/web/assets.cpp PROPERTIES
    COMPILE_DEFINITIONS INSTAINPAINT_WEB_PAGE)
  message(STATUS "Web page: bundled and embedded (${WEB_DIR})")
else()
  message(STATUS "Web page: not built (no ${WEB_ESBUILD}; run `make deps`)")
endif()
if(EXISTS ${WEB_DIR})
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${WEB_DIR})
endif()
