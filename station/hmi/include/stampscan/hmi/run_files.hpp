// The files of the runs folder as the panel serves them. Every name that comes from a URL is
// checked here before it touches the file system: a run id or file name is one path component of
// letters, digits, '.', '-' and '_' that does not start with '.', and what it names must be a
// regular file directly inside the runs folder's run. Anything else is refused (RunFileError), so
// "../", encoded slashes or a symlink out of the folder never serve a file outside it.
//
// Thread safety: the functions touch only their arguments and the files named.
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>

namespace stampscan::hmi {

class RunFileError : public std::runtime_error {
 public:
  RunFileError(int status, const std::string& what) : std::runtime_error(what), status_(status) {}
  int status() const { return status_; }  // the HTTP status to answer with: 400 or 404

 private:
  int status_;
};

// True when `name` is one safe path component (see above).
bool isSafeName(const std::string& name);
// The folder of run `run_id`; throws RunFileError 400 for an unsafe id, 404 when there is no such run.
std::filesystem::path runFolder(const std::filesystem::path& runs_dir, const std::string& run_id);
// A file of that run; throws RunFileError 400 for an unsafe name, 404 when it is not a regular
// file inside the run folder (after resolving symlinks).
std::filesystem::path runFile(const std::filesystem::path& runs_dir, const std::string& run_id, const std::string& name);
// The MIME type for a file name's extension.
std::string contentType(const std::string& name);
// mesh.ply as JSON for three.js: {"positions": [x,y,z,...], "indices": [...], "strain": [...]}
// (strain: thickness true strain per vertex, when the mesh has it). Throws RunFileError 404 when the
// run has no mesh, std::runtime_error when it cannot be read.
std::string meshJson(const std::filesystem::path& ply);

}  // namespace stampscan::hmi
