#pragma once
// What a job guarantees about its outputs (implemented in files.cc):
//
// - Writers replace only regular files: the commit step of every atomic write
//   (CommitTemporaryFile, WriteFileAtomic, WriteViaTemporary) refuses an
//   existing output that is a device, a FIFO, a socket or a folder.
// - One lock per output folder (OutputFolderLock): exclusive for a job that
//   owns the folder, shared for the cooperating shards of one build.
// - Interrupted jobs leave no temporaries: every temporary file or folder is
//   registered (TemporaryPathFor registers its paths), and SIGINT/SIGTERM
//   remove the registered paths and exit 130 (InstallInterruptHandlers).
//   SIGXFSZ is ignored, so a file-size limit is a write error (EFBIG) that
//   names the file.

#include <string>
#include <vector>

namespace geodrive {

// Throws InputError "<path>: exists and is not a regular file (a FIFO):
// refusing to replace it" when `path` exists (following links) and is not a
// regular file. An absent path passes.
void CheckReplaceableOutput(const std::string& path);

// Records a temporary file or folder, removed (folders with their contents)
// if the process is interrupted by SIGINT/SIGTERM. Paths that no longer exist
// at that time are skipped; the most recent 256 registrations are kept.
void RegisterTemporaryPath(const std::string& path);

// Removes every registered temporary path. Async-signal-safe (system calls
// only): the signal handlers call it.
void RemoveRegisteredTemporaries();

// SIGINT and SIGTERM: RemoveRegisteredTemporaries, then _exit(130) (locks are
// flocks: the kernel releases them). SIGXFSZ: ignored, so that writing past
// `ulimit -f` fails with EFBIG and the writer reports the file. Both binaries
// install these before running a command; a batch job may replace the
// SIGINT/SIGTERM handlers with a cooperative stop (InstallStopSignalHandlers,
// geometry/util/progress.h).
void InstallInterruptHandlers();

// No command writes over its own inputs: throws InputError naming `out` and
// the input when `out` is one of `inputs` (the same file, by inode, however
// spelled) or lies inside one that is a folder. Empty inputs are skipped.
void CheckOutputIsNotInput(const std::string& out,
                           const std::vector<std::string>& inputs);

// A lock on an output folder: flock on `path` (OUT/.lock), held while the
// object lives, released by the kernel when the process dies (kill -9
// included). kExclusive: the one job writing the folder. kShared: one of
// several cooperating jobs (the shards of one build); shared holders exclude
// an exclusive one and the other way round. Throws InputError naming `what`,
// the lock and its holder (a pid, or "shard runs") when it is held.
class OutputFolderLock {
 public:
  enum class Mode { kExclusive, kShared };
  OutputFolderLock(const std::string& path, const std::string& what, Mode mode);
  ~OutputFolderLock();
  OutputFolderLock(const OutputFolderLock&) = delete;
  OutputFolderLock& operator=(const OutputFolderLock&) = delete;

 private:
  int fd_ = -1;
};

// True when a process holds a lock (any mode) on the lock file `path`; false
// when it is free or absent. Probes with a non-blocking exclusive flock.
bool LockFileIsHeld(const std::string& path);

}  // namespace geodrive
