# Run by ctest after the discovered tests are defined (test_station_TESTS lists them). A test that
# runs `station scan`, `calibrate`, `verify`, `serve` or `devices` on the virtual cell hosts its fake
# GigE cameras, which share UDP 3956 on 127.0.0.1/127.0.0.2 with the camera driver tests and the
# panel's tests, so they take the same lock (see tests/drivers/camera/camera_test_lock.cmake).
# Every test takes it unless it is named below as needing no cell: a new test is safe by default
# (at worst it waits for the lock), where a list of the ones that need it missed new tests. The
# panel's service test takes it too: its cell's cameras are at addresses where none answers, so the
# panel's health check looks for them by their serials (the default ones), found the cameras of a
# scan hosted beside it and took control of one (the scan then failed: "controlled by another
# application").
set(_needs_no_cell
  "^StationTest\\.(Help|FitHelp|SampleAndDemoHelp|VersionFlag|NoSubcommandFails|UnknownSubcommandFails)"
  "^StationTest\\.(Fit|Sample|Demo|Trace|Sim|Process|NonexistentInput|InputsThatAreNot|BadBandwidth)"
  "^StationTest\\.(UnknownOptionValues|OutputIntoMissing|DevicesReportsAMissingCell|DevicesRejectsABadCellFile)"
  "^StationTest\\.(DryRunPrintsTheBuiltInPlan|CalibrationHistoryNamesAMissingOrCorruptRecord)"
  "^(StationCells|ScanShortfall|ScanDataLoss)\\." "^Inputs/StationMalformedTest\\." "^Methods/StationMethodTest\\.")
set(_served_cell_tests)
foreach(_test IN LISTS test_station_TESTS)
  set(_free FALSE)
  foreach(_pattern IN LISTS _needs_no_cell)
    if(_test MATCHES "${_pattern}")
      set(_free TRUE)
    endif()
  endforeach()
  if(NOT _free)
    list(APPEND _served_cell_tests "${_test}")
  endif()
endforeach()
set_tests_properties(${_served_cell_tests} PROPERTIES RESOURCE_LOCK stampscan_virtual_cameras)
# The scan beside a heavy load runs alone: the load would slow every test running beside it. So
# does the replay's equality test: it compares each replayed measurement with the recording's to
# 0.002 mm, and a scan running beside it on two cores (its surface fit included) delays the virtual
# devices' clock pairs enough to move the replayed ones by that much.
set_tests_properties(StationTest.TheDefaultScanBesideAHeavyLoadMeasuresThePartAsOnAnIdleMachine
                     StationTest.AReplayedScanGivesTheCloudOfItsRecording PROPERTIES RUN_SERIAL TRUE)
