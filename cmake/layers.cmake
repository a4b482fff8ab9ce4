# The module libraries and which way they depend: app -> {ui, bench} -> {edit, render} ->
# solver -> core, with edit/io below edit and the renderer's systems (render/display,
# render/hifi, render/holodeck) above render/. One table, checked two ways:
#   - includes: the test `layers` (scripts/check_layers.py) reads every header and source of
#     each module folder and fails naming the file, the line and the include when a file
#     includes a header of a module it may not use;
#   - links: penumbra_check_link_layers() at configure time fails when a module's library links
#     the library of a module it may not use.
# Each row: module folder | its libraries | the modules it may include and link besides itself
# (all of them, not only the next layer down). A subfolder that is not a row of its own
# (render/gl) belongs to the module of its parent.
set(PENUMBRA_BELOW_RENDER "solver,core")
set(PENUMBRA_BELOW_UI
    "edit,edit/io,render/display,render/hifi,render/holodeck,render,${PENUMBRA_BELOW_RENDER}")
set(PENUMBRA_LAYERS
    "core|penumbra_core|"
    "solver|penumbra_solver|core"
    "edit/io|penumbra_edit_io|${PENUMBRA_BELOW_RENDER}"
    "edit|penumbra_edit|edit/io,${PENUMBRA_BELOW_RENDER}"
    "render|penumbra_render,penumbra_offscreen|${PENUMBRA_BELOW_RENDER}"
    "render/display|penumbra_display|render,${PENUMBRA_BELOW_RENDER}"
    "render/hifi|penumbra_hifi,penumbra_cdt,penumbra_interpolant_gl|render,${PENUMBRA_BELOW_RENDER}"
    # The holodeck shades its samples with the display's PointShader and hands them to the
    # display's render cache (Ward & Simmons' ray cache feeding Bala et al.'s display); the
    # display knows nothing of the holodeck.
    "render/holodeck|penumbra_holodeck|render/display,render,${PENUMBRA_BELOW_RENDER}"
    "ui|penumbra_ui|${PENUMBRA_BELOW_UI}"
    "bench|penumbra_bench|${PENUMBRA_BELOW_UI}"
    "app|penumbra_mpi,penumbra_cli|ui,bench,${PENUMBRA_BELOW_UI}"
    "fuzz||${PENUMBRA_BELOW_UI}")

# penumbra_check_link_layers(): every library of the table links only its own module's and the
# allowed modules' libraries (PRIVATE and PUBLIC alike). Libraries outside the table
# (penumbra_glad, the ImGui backends) are third-party wrappers and not checked.
function(penumbra_check_link_layers)
  foreach(row ${PENUMBRA_LAYERS})
    string(REPLACE "|" ";" parts "${row}")
    list(GET parts 0 module)
    list(GET parts 1 libraries)
    string(REPLACE "," ";" libraries "${libraries}")
    foreach(library ${libraries})
      set(module_of_${library} ${module})
    endforeach()
  endforeach()
  set(errors "")
  foreach(row ${PENUMBRA_LAYERS})
    string(REPLACE "|" ";" parts "${row}")
    list(GET parts 0 module)
    list(GET parts 1 libraries)
    list(GET parts 2 allowed)
    string(REPLACE "," ";" libraries "${libraries}")
    string(REPLACE "," ";" allowed "${allowed}")
    foreach(library ${libraries})
      if(NOT TARGET ${library})
        continue()
      endif()
      get_target_property(links ${library} LINK_LIBRARIES)
      if(NOT links)
        continue()
      endif()
      foreach(link ${links})
        if(NOT DEFINED module_of_${link})
          continue()
        endif()
        set(to ${module_of_${link}})
        if(NOT to STREQUAL module AND NOT to IN_LIST allowed)
          string(APPEND errors "\n  ${library} (${module}/) links ${link} (${to}/)")
        endif()
      endforeach()
    endforeach()
  endforeach()
  if(errors)
    message(FATAL_ERROR "Upward link dependencies (cmake/layers.cmake):${errors}")
  endif()
endfunction()
