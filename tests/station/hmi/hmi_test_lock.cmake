# Run by ctest after the discovered tests are defined (test_hmi_TESTS lists them): every test of
# test_hmi starts `station hmi` on the virtual cell, whose fake GigE cameras hold UDP 3956 on
# 127.0.0.1/127.0.0.2, so they take the lock of the other tests that serve cameras
# (tests/station/station_test_lock.cmake).
set_tests_properties(${test_hmi_TESTS} PROPERTIES RESOURCE_LOCK stampscan_virtual_cameras)
