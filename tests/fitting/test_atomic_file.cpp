// Output files appear whole or not at all: unique temporaries, commit by rename, sets replaced
// together, temporaries removed when the process is interrupted.
#include "stampscan/fitting/atomic_file.hpp"

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace fs = std::filesystem;
using stampscan::fitting::AtomicFile;

namespace {

fs::path freshDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("stampscan-atomic-" + name + "-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::string readAll(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::vector<fs::path> entries(const fs::path& dir) {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path().filename());
  return out;
}

void writeText(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
}

}  // namespace

// A pipe or a device named as the output (a FIFO, /dev/null, /dev/stdout) is written into, never
// replaced by a plain file.
TEST(AtomicFile, APipeNamedAsTheTargetIsWrittenIntoAndStaysAPipe) {
  const fs::path dir = freshDir("fifo");
  const fs::path fifo = dir / "out.ply";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] {
    std::ifstream in(fifo, std::ios::binary);
    std::ostringstream all;
    all << in.rdbuf();
    received = all.str();
  });
  stampscan::fitting::writeFileAtomically(fifo, "whole contents\n");
  reader.join();
  EXPECT_EQ(received, "whole contents\n");
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_EQ(entries(dir).size(), 1u) << "the temporary is removed";
}

TEST(AtomicFile, TemporaryNamesAreUniqueAndBesideTheTarget) {
  const fs::path dir = freshDir("names");
  std::set<fs::path> names;
  std::vector<std::unique_ptr<AtomicFile>> files;
  for (int i = 0; i < 200; ++i) {
    files.push_back(std::make_unique<AtomicFile>(dir / "out.ply"));
    EXPECT_EQ(files.back()->temporaryPath().parent_path(), dir);
    names.insert(files.back()->temporaryPath());
  }
  EXPECT_EQ(names.size(), 200u);
  fs::remove_all(dir);
}

TEST(AtomicFile, CommitReplacesTheTargetAndAnUncommittedOneLeavesNothing) {
  const fs::path dir = freshDir("commit");
  writeText(dir / "a.txt", "old");
  {
    AtomicFile file(dir / "a.txt");
    writeText(file.temporaryPath(), "new");
    EXPECT_EQ(readAll(dir / "a.txt"), "old");  // readers see the old file until the commit
    file.commit();
  }
  EXPECT_EQ(readAll(dir / "a.txt"), "new");
  {
    AtomicFile file(dir / "a.txt");
    writeText(file.temporaryPath(), "abandoned halfway");
  }  // an exception or early return: the destructor removes the temporary
  EXPECT_EQ(readAll(dir / "a.txt"), "new");
  EXPECT_EQ(entries(dir).size(), 1u);
  fs::remove_all(dir);
}

TEST(AtomicFile, CommitWithoutATemporaryNamesTheTarget) {
  const fs::path dir = freshDir("missing");
  AtomicFile file(dir / "never-written.json");
  try {
    file.commit();
    FAIL() << "a commit without content must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("never-written.json"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

TEST(AtomicFile, ConcurrentWritersToOneTargetLeaveOneWholeFile) {
  const fs::path dir = freshDir("concurrent");
  const fs::path target = dir / "trace.mcap";
  std::vector<std::thread> writers;
  for (int w = 0; w < 8; ++w) {
    writers.emplace_back([&, w] {
      // Each writer's content is one repeated letter: a mixture of two would show.
      stampscan::fitting::writeFileAtomically(target, std::string(1 << 16, static_cast<char>('a' + w)));
    });
  }
  for (auto& t : writers) t.join();
  const std::string content = readAll(target);
  ASSERT_EQ(content.size(), std::size_t{1} << 16);
  EXPECT_EQ(content.find_first_not_of(content[0]), std::string::npos) << "two writers' contents were mixed";
  EXPECT_EQ(entries(dir).size(), 1u) << "temporaries were left behind";
  fs::remove_all(dir);
}

TEST(AtomicFile, ASetIsReplacedWholeAndFilesTheNewSetLacksAreRemoved) {
  const fs::path dir = freshDir("set");
  writeText(dir / "digitizer.json", "old digitizer");
  writeText(dir / "cameras.json", "old cameras");
  {
    AtomicFile digitizer(dir / "digitizer.json");
    writeText(digitizer.temporaryPath(), "new digitizer");
    stampscan::fitting::commitTogether({&digitizer}, {dir / "cameras.json"});
  }
  EXPECT_EQ(readAll(dir / "digitizer.json"), "new digitizer");
  EXPECT_FALSE(fs::exists(dir / "cameras.json")) << "an old file of the previous set was left beside the new one";

  // A member of the set that was never written stops the whole set before anything is renamed.
  AtomicFile digitizer(dir / "digitizer.json"), cameras(dir / "cameras.json");
  writeText(digitizer.temporaryPath(), "newer digitizer");
  EXPECT_THROW(stampscan::fitting::commitTogether({&digitizer, &cameras}), std::runtime_error);
  EXPECT_EQ(readAll(dir / "digitizer.json"), "new digitizer");
  fs::remove_all(dir);
}

TEST(AtomicFile, ASignalRemovesPendingTemporariesAndStillEndsTheProcess) {
  const fs::path dir = freshDir("signal");
  for (const int signal_number : {SIGINT, SIGTERM, SIGHUP}) {
    const pid_t child = fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      stampscan::fitting::removeTemporariesOnSignals();
      AtomicFile a(dir / "a.ply"), b(dir / "b.ply");
      writeText(a.temporaryPath(), "half");
      writeText(b.temporaryPath(), "half");
      ::raise(signal_number);
      ::_exit(0);  // not reached: the handler ends the process by the signal
    }
    int status = 0;
    ASSERT_EQ(waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFSIGNALED(status)) << "the process must still end by the signal, as without the handler";
    EXPECT_EQ(WTERMSIG(status), signal_number);
    EXPECT_TRUE(entries(dir).empty()) << "temporaries left after signal " << signal_number;
  }
  fs::remove_all(dir);
}

// A writer killed outright (SIGKILL, a power cut) leaves its temporary: the next writer of the same
// file removes it, and leaves alone the temporaries of writers that still run.
TEST(AtomicFile, TheNextWriterRemovesTheTemporaryOfAKilledOne) {
  const fs::path dir = freshDir("orphans");
  const fs::path target = dir / "trace.mcap";
  // A process that has ended: its id is free (until reused, when its temporary is left alone).
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) _exit(0);
  waitpid(child, nullptr, 0);
  const fs::path orphan = dir / ("trace.mcap.tmp-" + std::to_string(child) + "-0123456789ab");
  const fs::path running = dir / ("trace.mcap.tmp-" + std::to_string(::getppid()) + "-0123456789ab");
  const fs::path other_file = dir / ("other.mcap.tmp-" + std::to_string(child) + "-0123456789ab");
  const fs::path unparsed = dir / "trace.mcap.tmp-notapid";
  for (const fs::path& f : {orphan, running, other_file, unparsed}) writeText(f, "half");
  {
    AtomicFile file(target);
    EXPECT_NE(file.temporaryPath().filename().string().find(".tmp-" + std::to_string(::getpid()) + "-"),
              std::string::npos)
        << file.temporaryPath();
    EXPECT_FALSE(fs::exists(orphan)) << "the killed writer's temporary is removed";
    writeText(file.temporaryPath(), "whole");
    file.commit();
  }
  EXPECT_TRUE(fs::exists(running)) << "a running writer's temporary is left alone";
  EXPECT_TRUE(fs::exists(other_file)) << "another file's temporaries are not this writer's";
  EXPECT_TRUE(fs::exists(unparsed));
  EXPECT_EQ(readAll(target), "whole");
  fs::remove_all(dir);
}
