// Client-streaming upload of a file in chunks of at most 1 MiB, shared by the
// result (UploadResult) and checkpoint (UploadCheckpoint) uploads.
#pragma once

#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

namespace cellflow::worker {

// Sends `path` through `writer` as Chunk messages (offset + data); the first
// chunk, sent even for an empty file, gets its header fields from
// `fill_first(chunk)`. Returns the call's status (NOT_FOUND "no <what>"
// without the file).
template <class Chunk, class FillFirst>
grpc::Status upload_file_chunks(std::unique_ptr<grpc::ClientWriterInterface<Chunk>> writer,
                                const std::filesystem::path& path, const char* what, FillFirst fill_first) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return {grpc::StatusCode::NOT_FOUND, std::string("no ") + what};
  if (!writer) return {grpc::StatusCode::UNIMPLEMENTED, "no upload stream"};
  std::vector<char> buffer(1 << 20);
  std::int64_t offset = 0;
  bool first = true;
  while (in || first) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    const std::streamsize n = in.gcount();
    if (n == 0 && !first) break;
    Chunk chunk;
    if (first) fill_first(chunk);
    first = false;
    chunk.set_offset(offset);
    chunk.set_data(buffer.data(), static_cast<std::size_t>(n));
    if (!writer->Write(chunk)) break;
    offset += n;
  }
  writer->WritesDone();
  return writer->Finish();
}

}  // namespace cellflow::worker
