// Uploaded meshes: Gmsh .msh bytes validated with the bounded reader and kept
// in the data directory as meshes/<sha256>.msh, named by the lowercase hex
// SHA-256 of their bytes (content addressed: the same mesh twice is stored
// once). A spec refers to one by CellSpec.mesh_sha256; no request names a
// file of the server's machine. No gRPC here.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "cellflow/v1/service.pb.h"
#include "physics/core/status.h"
#include "server/encoding.h"  // sha256_hex, is_sha256_hex

namespace cellflow::server {

class MeshStore {
 public:
  MeshStore(std::filesystem::path dir, std::uint64_t max_bytes);

  // Reads `bytes` with the bounded reader (limits: max_bytes, and node and
  // element counts) and stores them under their hash. INVALID_ARGUMENT (not a
  // mesh) or RESOURCE_EXHAUSTED (over a limit); messages never repeat the
  // bytes. `name` only appears in messages.
  StatusOr<v1::MeshRef> put(const std::string& bytes, std::string_view name);
  bool contains(std::string_view sha256) const;
  // The stored bytes; NOT_FOUND for an unknown hash.
  StatusOr<std::string> get(std::string_view sha256) const;
  std::uint64_t max_bytes() const { return max_bytes_; }

 private:
  std::filesystem::path path_of(std::string_view sha256) const;
  std::filesystem::path dir_;
  std::uint64_t max_bytes_;
};

}  // namespace cellflow::server
