// Private to the write stage: streamed encoding (image_png.cpp,
// image_exr.cpp). ordered_pieces() makes a file's pieces in parallel and
// hands them over in order; StreamFile writes them as they come. The first
// failed write is remembered and later pieces are dropped (the pipeline
// still runs to its end); close() reports it, naming the file.
#pragma once

#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>

#include "nmbake/common.hpp"

namespace nmbake::image_detail {

// Pieces 0 to count - 1: make(i) returns piece i as a std::unique_ptr, run
// in parallel with a few pieces per core in flight; take(piece) gets them in
// index order, one at a time.
template <class Piece, class Make, class Take>
void ordered_pieces(std::size_t count, Make&& make, Take&& take) {
  std::size_t next = 0;
  const std::size_t in_flight =
      4 * static_cast<std::size_t>(std::max(1, tbb::this_task_arena::max_concurrency()));
  tbb::parallel_pipeline(
      in_flight, tbb::make_filter<void, std::size_t>(tbb::filter_mode::serial_in_order,
                                                     [&](tbb::flow_control& fc) -> std::size_t {
                                                       if (next == count) {
                                                         fc.stop();
                                                         return 0;
                                                       }
                                                       return next++;
                                                     }) &
                     tbb::make_filter<std::size_t, std::unique_ptr<Piece>>(tbb::filter_mode::parallel, make) &
                     tbb::make_filter<std::unique_ptr<Piece>, void>(
                         tbb::filter_mode::serial_in_order,
                         [&](std::unique_ptr<Piece> piece) { take(std::move(piece)); }));
}

class StreamFile {
 public:
  StreamFile(const std::string& path, std::string display_path)
      : file_(std::fopen(path.c_str(), "wb")), display_path_(std::move(display_path)) {
    if (file_ == nullptr) error_ = errno;
  }
  StreamFile(const StreamFile&) = delete;
  StreamFile& operator=(const StreamFile&) = delete;
  ~StreamFile() {
    if (file_ != nullptr) std::fclose(file_);
  }

  // False (with open_status() saying why) when the file could not be created.
  bool is_open() const { return file_ != nullptr; }
  Status open_status() const { return failure(error_); }

  void put(const std::uint8_t* data, std::size_t size) {
    if (error_ == 0 && std::fwrite(data, 1, size, file_) != size) error_ = errno != 0 ? errno : EIO;
  }
  // Overwrites bytes already written (a table known only at the end).
  void put_at(std::size_t offset, const std::uint8_t* data, std::size_t size) {
    if (error_ == 0 && std::fseek(file_, static_cast<long>(offset), SEEK_SET) != 0)
      error_ = errno != 0 ? errno : EIO;
    put(data, size);
  }

  Status close() {
    const bool closed = std::fclose(file_) == 0;
    file_ = nullptr;
    if (error_ == 0 && !closed) error_ = errno != 0 ? errno : EIO;
    return error_ == 0 ? Status::ok() : failure(error_);
  }

 private:
  Status failure(int error) const {
    return Status::io("cannot write '" + display_path_ + "': " + std::strerror(error));
  }

  std::FILE* file_;
  std::string display_path_;
  int error_ = 0;
};

}  // namespace nmbake::image_detail
