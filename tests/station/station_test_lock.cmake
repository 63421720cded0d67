# Run by ctest after the discovered tests are defined: the test that serves the virtual cell starts
# the fake GigE cameras, which share UDP 3956 on 127.0.0.1/127.0.0.2 with the camera driver tests,
# so it takes the same lock (see tests/drivers/camera/camera_test_lock.cmake).
set_tests_properties(StationTest.DevicesFindsTheServedVirtualCell PROPERTIES RESOURCE_LOCK stampscan_virtual_cameras)
