#include "io/afm/zip_archive.h"

#include <zip.h>

#include <algorithm>

namespace cellflow::afm {

void ZipArchive::Closer::operator()(zip* z) const {
  if (z != nullptr) zip_discard(z);  // read-only: never write back
}

StatusOr<ZipArchive> ZipArchive::open(const std::string& bytes, std::string label, const ZipLimits& limits) {
  zip_error_t err;
  zip_error_init(&err);
  zip_source_t* src = zip_source_buffer_create(bytes.data(), bytes.size(), 0, &err);
  if (src == nullptr) {
    Status s = invalid_argument(label + ": cannot read as zip: " + zip_error_strerror(&err));
    zip_error_fini(&err);
    return s;
  }
  zip_t* z = zip_open_from_source(src, ZIP_RDONLY | ZIP_CHECKCONS, &err);
  if (z == nullptr) {
    zip_source_free(src);
    Status s = invalid_argument(
        label + ": not a readable zip archive (truncated or corrupt?): " + zip_error_strerror(&err));
    zip_error_fini(&err);
    return s;
  }
  zip_error_fini(&err);
  ZipArchive archive(std::unique_ptr<zip, Closer>(z), std::move(label), limits);

  const zip_int64_t count = zip_get_num_entries(z, 0);
  if (count < 0 || static_cast<std::uint64_t>(count) > limits.max_entries) {
    return invalid_argument(archive.label_ + ": " + std::to_string(count) +
                            " zip entries exceeds the limit of " + std::to_string(limits.max_entries));
  }
  std::uint64_t total = 0;
  for (zip_int64_t i = 0; i < count; ++i) {
    zip_stat_t st;
    zip_stat_init(&st);
    if (zip_stat_index(z, static_cast<zip_uint64_t>(i), 0, &st) != 0 || !(st.valid & ZIP_STAT_NAME) ||
        !(st.valid & ZIP_STAT_SIZE)) {
      return invalid_argument(archive.label_ + ": zip entry " + std::to_string(i) + " has no name or size");
    }
    if (st.size > limits.max_entry_bytes) {
      return Status(StatusCode::kResourceExhausted,
                    archive.label_ + ": zip entry '" + st.name + "' declares " + std::to_string(st.size) +
                        " bytes uncompressed, over the limit of " + std::to_string(limits.max_entry_bytes));
    }
    total += st.size;
    if (total > limits.max_total_bytes) {
      return Status(StatusCode::kResourceExhausted, archive.label_ + ": zip entries declare more than " +
                                                        std::to_string(limits.max_total_bytes) +
                                                        " bytes uncompressed in all");
    }
    archive.names_.emplace_back(st.name);
    archive.sizes_.push_back(st.size);
  }
  return archive;
}

bool ZipArchive::contains(const std::string& name) const {
  return std::find(names_.begin(), names_.end(), name) != names_.end();
}

StatusOr<std::string> ZipArchive::read(const std::string& name) const {
  const auto it = std::find(names_.begin(), names_.end(), name);
  if (it == names_.end())
    return Status(StatusCode::kNotFound, label_ + ": zip entry '" + name + "' is missing");
  const auto index = static_cast<std::size_t>(it - names_.begin());
  const std::uint64_t size = sizes_[index];
  zip_file_t* f = zip_fopen_index(zip_.get(), index, 0);
  if (f == nullptr) {
    return invalid_argument(label_ + ": zip entry '" + name + "': " + zip_strerror(zip_.get()));
  }
  std::string out(static_cast<std::size_t>(size), '\0');
  std::uint64_t done = 0;
  Status status;
  while (done < size) {
    const zip_int64_t n = zip_fread(f, out.data() + done, size - done);
    if (n < 0) {
      status = invalid_argument(label_ + ": zip entry '" + name + "': " + zip_file_strerror(f));
      break;
    }
    if (n == 0) break;
    done += static_cast<std::uint64_t>(n);
  }
  // One byte more must be end of data: an entry that inflates past its
  // declared size is corrupt (or hostile).
  char extra = 0;
  if (status.ok() && done == size && zip_fread(f, &extra, 1) > 0) {
    status = invalid_argument(label_ + ": zip entry '" + name + "' inflates past its declared size");
  }
  zip_fclose(f);
  if (!status.ok()) return status;
  if (done != size) {
    return invalid_argument(label_ + ": zip entry '" + name + "' is truncated: " + std::to_string(done) +
                            " of " + std::to_string(size) + " bytes");
  }
  return out;
}

}  // namespace cellflow::afm
