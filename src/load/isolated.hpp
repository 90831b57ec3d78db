// Private to the loaders: running a third-party reader in a process of its
// own, so that a crash or a runaway allocation inside it is an error naming
// the file (exit 2), not the end of nmbake.
//
// Why: Debian's Assimp 5.2.5 crashes (SIGSEGV) on some broken Collada files
// and allocates whatever a count in a file says (an 8.6 KB .dae took 18.9 GB
// and 110 s before failing), both found by tests/fuzz/fuzz_assimp. We cannot
// fix the library, so it reads in a child (fork()), whose address space is
// capped at the memory available (memory.hpp; not in sanitizer builds, whose
// shadow memory needs terabytes of it), and sends the mesh back through a pipe.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "nmbake/load.hpp"

namespace nmbake::load_detail {

// The child's CPU time is capped at kChildCpuSeconds plus a second per
// kChildBytesPerCpuSecond of file (far above what a real file needs: Assimp
// reads a binary FBX at over 100 MB/s), and the parent kills a child still
// running kChildWallFactor times that long by the clock (one that waits
// instead of computing). Either is bad_input naming the file and the limit.
// (A mutated 3 KB file kept Assimp busy past fuzz_assimp's 10 s timeout.)
constexpr std::uint64_t kChildCpuSeconds = 2;
constexpr std::uint64_t kChildBytesPerCpuSecond = std::uint64_t{1} << 20;
constexpr std::uint64_t kChildWallFactor = 10;
std::uint64_t child_cpu_seconds(std::uint64_t file_bytes);

// `load` runs in the child; it calls `read_done()` once the library has
// returned its scene, so that a crash after that point (in our conversion
// code) is reported as ours (internal, exit 3), one before it as the file's
// (bad_input naming `library`). The child is single-threaded: `load` must not
// use TBB. On success `out` and `stats` are what `load` filled in the child.
using ChildLoad = std::function<Status(Mesh& out, LoadStats& stats, const std::function<void()>& read_done)>;
Status load_in_child(const std::string& path, const char* library, const ChildLoad& load, Mesh& out,
                     LoadStats& stats);

// The child's reply through the pipe (the child writes it piece by piece;
// these are the same format as one string, for tests): 'R', 'S', the status
// and, when it is ok, every mesh array (colours too), the parts and
// materials, and the stats. decode_child_reply() returns false for a reply
// that is cut short or malformed, and checks every count against the bytes
// left before it allocates (a count that claims more is malformed); true
// with `status` set otherwise (`mesh` and `stats` filled when it is ok).
std::string encode_child_reply(const Status& status, const Mesh& mesh, const LoadStats& stats);
bool decode_child_reply(const std::string& data, Status& status, Mesh& mesh, LoadStats& stats);

}  // namespace nmbake::load_detail
