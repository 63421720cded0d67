# Run by ctest after the discovered camera tests are defined (test_drivers_camera_TESTS lists them):
# the suites that start fake cameras share UDP 3956 on 127.0.0.1/127.0.0.2, so they must not run
# concurrently (ctest -j) with each other nor with the other tests that serve the virtual cameras
# (tests/station, tests/station/hmi, the ScanRunner's stereo suite), which take the same lock.
set_tests_properties(${test_drivers_camera_TESTS} PROPERTIES RESOURCE_LOCK stampscan_virtual_cameras)
