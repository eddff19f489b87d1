# The PyPI message wheels export their Python generator targets with the include folders of the
# machine that built them (/opt/python/...), which CMake refuses: point them at this venv's
# Python and NumPy headers (PYTHON_INCLUDE_DIRS, given by build.sh). Included by every test-only
# message package (vision_msgs, ../tf2_msgs) after its find_package calls.
foreach(package builtin_interfaces std_msgs geometry_msgs)
  if(TARGET ${package}::${package}__rosidl_generator_py)
    set_target_properties(${package}::${package}__rosidl_generator_py PROPERTIES
      INTERFACE_INCLUDE_DIRECTORIES "${PYTHON_INCLUDE_DIRS}")
  endif()
endforeach()
