/* empty: cffi knows the standard types; see CMakeLists.txt (DV_BUILD_PYTHON) */
