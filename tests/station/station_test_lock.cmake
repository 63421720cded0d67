# Run by ctest after the discovered tests are defined: the tests that serve the virtual cell start
# the fake GigE cameras, which share UDP 3956 on 127.0.0.1/127.0.0.2 with the camera driver tests,
# so they take the same lock (see tests/drivers/camera/camera_test_lock.cmake).
set(_served_cell_tests
  StationTest.DevicesFindsTheServedVirtualCell StationTest.ArvToolTalksToTheServedCameras
  StationTest.AFaultInOneServedDeviceLeavesTheOthersRunning
  # the network probes, when no private network namespace can be made
  NetworkProbe.HostileAndRandomGvcpDatagramsLeaveTheCellAnswering
  NetworkProbe.RandomModbusFramesAndIppLinesLeaveTheCellAnswering
  NetworkProbe.IdleConnectionsAndASlowReaderAreLetGo
  NetworkProbe.ServersShortOfFileDescriptorsBackOffAndRecover
  StationTest.MbpollReadsTheServedPlc StationTest.RawTcpClientDrivesTheServedCmm
  # `station scan` hosts the virtual cell with its cameras
  StationTest.ScanOnTheVirtualCellMeasuresThePart StationTest.CtrlCEndsAScanCleanly
  StationTest.TheLiveTraceOpensInTheReferenceReader StationTest.ScanRefusesAPlanBeforeAnythingMoves
  # `station calibrate` of the cameras
  StationTest.CalibrateRecoversTheVirtualCellsSensorsAndPutsThemInUse
  StationTest.AFailedCalibrationIsKeptOutOfUseUnlessAccepted StationTest.CalibrateLeavesOutTheViewsThatSpoilAFit
  # the second cell's virtual twin, with its cameras
  StationTest.ASecondCellFromItsFileScansThePartToTheSameGoals
  StationTest.ASecondCellIsCheckedCalibratedAndVerifiedFromItsFile)
set_tests_properties(${_served_cell_tests} PROPERTIES RESOURCE_LOCK stampscan_virtual_cameras)
# The scan beside a heavy load runs alone: the load would slow every test running beside it. So
# does the replay's equality test: it compares each replayed measurement with the recording's to
# 0.002 mm, and a scan running beside it on two cores (its surface fit included) delays the virtual
# devices' clock pairs enough to move the replayed ones by that much.
set_tests_properties(StationTest.TheDefaultScanBesideAHeavyLoadMeasuresThePartAsOnAnIdleMachine
                     StationTest.AReplayedScanGivesTheCloudOfItsRecording PROPERTIES RUN_SERIAL TRUE)
