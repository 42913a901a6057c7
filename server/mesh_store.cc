#include "server/mesh_store.h"

#include <fcntl.h>
#include <unistd.h>

#include <fstream>
#include <memory>
#include <sstream>
#include <system_error>

#include "physics/mesh/sphere_mesh.h"

namespace cellflow::server {

namespace fs = std::filesystem;

MeshStore::MeshStore(fs::path dir, std::uint64_t max_bytes) : dir_(std::move(dir)), max_bytes_(max_bytes) {
  std::error_code error;
  fs::create_directories(dir_, error);
}

fs::path MeshStore::path_of(std::string_view sha256) const {
  return dir_ / (std::string(sha256) + ".msh");
}

StatusOr<v1::MeshRef> MeshStore::put(const std::string& bytes, std::string_view name) {
  if (bytes.size() > max_bytes_) {
    return Status(StatusCode::kResourceExhausted, "mesh: " + std::to_string(bytes.size()) +
                                                      " bytes, over this server's limit of " +
                                                      std::to_string(max_bytes_) + " (--max-mesh-bytes)");
  }
  mesh::MeshReadLimits limits;
  limits.max_bytes = max_bytes_;
  StatusOr<mesh::TetMesh> mesh = mesh::read_gmsh_msh_from_bytes(bytes, name, 1.0, limits);
  if (!mesh.ok()) {
    const StatusCode code = mesh.status().code() == StatusCode::kResourceExhausted
                                ? StatusCode::kResourceExhausted
                                : StatusCode::kInvalidArgument;
    return Status(code, "mesh: " + mesh.status().message());
  }
  v1::MeshRef ref;
  ref.set_sha256(sha256_hex(bytes));
  if (!is_sha256_hex(ref.sha256())) return Status(StatusCode::kInternal, "mesh: cannot hash the upload");
  ref.set_size_bytes(static_cast<std::int64_t>(bytes.size()));
  ref.set_vertex_count(static_cast<std::int64_t>(mesh->num_vertices()));
  ref.set_tet_count(static_cast<std::int64_t>(mesh->num_tets()));
  const fs::path path = path_of(ref.sha256());
  std::error_code error;
  if (fs::exists(path, error)) return ref;
  // Written under a temporary name, synced and renamed: a reader never sees half a mesh.
  const fs::path temporary = path.string() + ".part";
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Status(StatusCode::kInternal, "mesh: cannot create the mesh file");
  std::size_t written = 0;
  while (written < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + written, bytes.size() - written);
    if (n <= 0) {
      ::close(fd);
      fs::remove(temporary, error);
      return Status(StatusCode::kInternal, "mesh: cannot write the mesh file");
    }
    written += static_cast<std::size_t>(n);
  }
  const bool synced = ::fsync(fd) == 0;
  ::close(fd);
  if (!synced) {
    fs::remove(temporary, error);
    return Status(StatusCode::kInternal, "mesh: cannot sync the mesh file");
  }
  fs::rename(temporary, path, error);
  if (error) return Status(StatusCode::kInternal, "mesh: cannot store the mesh file");
  return ref;
}

bool MeshStore::contains(std::string_view sha256) const {
  std::error_code error;
  return is_sha256_hex(sha256) && fs::is_regular_file(path_of(sha256), error);
}

StatusOr<std::string> MeshStore::get(std::string_view sha256) const {
  if (!contains(sha256)) {
    return Status(StatusCode::kNotFound, "no uploaded mesh has this mesh_sha256; upload it (UploadMesh)");
  }
  std::ifstream in(path_of(sha256), std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  if (!in && !in.eof()) return Status(StatusCode::kInternal, "cannot read a stored mesh");
  return bytes.str();
}

}  // namespace cellflow::server
