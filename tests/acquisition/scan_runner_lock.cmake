# Run by ctest after the discovered tests are defined: the stereo suites of the ScanRunner start the
# virtual cameras, which share UDP 3956 on 127.0.0.1/127.0.0.2 with the camera driver tests, so they
# take the same lock (see tests/drivers/camera/camera_test_lock.cmake).
set_tests_properties(ScanRunnerStereoTest.EachViewIsAPairOfFramesOfTheWorld
  ScanRunnerStereoTest.ALostCameraMarksItsViewsMissingAndTheScanGoesOn PROPERTIES RESOURCE_LOCK stampscan_virtual_cameras)
