# Run by ctest after the discovered camera tests are defined: the suites that start fake cameras
# share UDP 3956 on 127.0.0.1/127.0.0.2, so they must not run concurrently (ctest -j).
# (`if(TEST ...)` does not see tests in ctest's script mode, so the names are listed outright.)
set(_camera_tests
  CameraDiscovery.FindsBothBySerial CameraDiscovery.FindsBothByAddress
  CameraDiscovery.UnknownSerialIsAClearError CameraDiscovery.ArvToolListsBothCameras
  CameraConfigTest.RoundTrip CameraConfigTest.RefusedValueNamesTheFeature
  CameraStream.BothCamerasDeliverTheSuppliedImages CameraStream.SoftwareTriggerGivesOneFramePerTrigger
  CameraStream.FullResolutionFrameRate
  CameraFaults.IncompleteFramesAreCountedNotDelivered CameraFaults.DisappearingCameraIsReportedAndReconnected
  CameraFaults.ExplicitReconnectRestoresTheConfiguration
  StereoCameras.SoftwareTriggeredPairs
  CameraHardening.HostileRequestsGetTheirErrorStatusAndTheCameraStreamsOn
  CameraHardening.RandomAndMutatedDatagramsLeaveBothCamerasAnsweringAndStreaming
  CameraHardening.ListensOnLoopbackOnly CameraHardening.SecondControllerIsReportedQuickly
  CameraHardening.AnAbandonedControllerLosesTheCameraAfterItsHeartbeatTimeout)
set_tests_properties(${_camera_tests} PROPERTIES RESOURCE_LOCK stampscan_virtual_cameras)
