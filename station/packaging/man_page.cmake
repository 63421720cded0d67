# Writes the man page of `station` from its own help: the program's, then each command's.
#   cmake -DSTATION=path/to/station -DVERSION=x.y.z -DOUT=station.1 -P man_page.cmake
execute_process(COMMAND ${STATION} --help OUTPUT_VARIABLE main_help RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${STATION} --help failed (${rc})")
endif()

# roff: backslashes escaped, a line that starts with a dot or a quote kept as text.
function(as_roff text out)
  string(REPLACE "\\" "\\e" text "${text}")
  string(REGEX REPLACE "(^|\n)([.'])" "\\1\\\\&\\2" text "${text}")
  set(${out} "${text}" PARENT_SCOPE)
endfunction()

string(REGEX REPLACE "Usage: [^ ]+" "Usage: station" main_help "${main_help}")
string(REGEX MATCH "Subcommands:\n.*" commands_text "${main_help}")
string(REGEX MATCHALL "\n  [a-z][a-z0-9-]*  " command_lines "${commands_text}")
string(TIMESTAMP today "%Y-%m-%d" UTC)  # SOURCE_DATE_EPOCH, when set, makes it reproducible

set(page ".TH STATION 1 \"${today}\" \"StampScan ${VERSION}\" \"User Commands\"\n")
string(APPEND page ".SH NAME\nstation \\- sheet-metal forming inspection: scan, fit, strain map\n")
string(APPEND page ".SH SYNOPSIS\n.B station\n.I COMMAND\n[\\fIOPTIONS\\fR]\n")
as_roff("${main_help}" main_roff)
string(APPEND page ".SH DESCRIPTION\n.nf\n${main_roff}\n.fi\n.SH COMMANDS\n")
foreach(line IN LISTS command_lines)
  string(STRIP "${line}" command)
  execute_process(COMMAND ${STATION} ${command} --help OUTPUT_VARIABLE help RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${STATION} ${command} --help failed (${rc})")
  endif()
  string(REGEX REPLACE "Usage: [^ ]+" "Usage: station" help "${help}")
  as_roff("${help}" help_roff)
  string(APPEND page ".SS ${command}\n.nf\n${help_roff}\n.fi\n")
endforeach()
string(APPEND page ".SH FILES\n.TP\n/etc/stampscan/cell.toml\nThe cell file: its devices, machine, head, sensors, artefacts, fixture, calibration rules, results database, part programs and panel.\n")
string(APPEND page ".TP\n/var/lib/stampscan/runs\nThe run folders and the results database of the panel's service.\n")
string(APPEND page ".SH SEE ALSO\n.BR nginx (8),\n.BR systemctl (1)\n")
file(WRITE "${OUT}" "${page}")
