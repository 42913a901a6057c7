#include "io/afm/read_force_curve.h"

#include "io/afm/format_readers.h"
#include "io/afm/safe_file.h"
#include "io/afm/text_util.h"

namespace cellflow::afm {
namespace {

bool ends_with_ci(const std::string& s, std::string_view suffix) {
  return s.size() >= suffix.size() &&
         to_lower(std::string_view(s).substr(s.size() - suffix.size())) == suffix;
}

}  // namespace

StatusOr<ForceCurve> read_force_curve(const std::string& path, const ReadOptions& options) {
  auto bytes = read_regular_file(path, options.max_file_bytes);
  if (!bytes.ok()) return bytes.status();
  const std::string& b = *bytes;

  // Content before extension: a renamed file still reads, and a text file
  // called .jpk-force gives a zip error that says what is wrong.
  const bool zip_magic = b.size() >= 4 && b.compare(0, 4, "PK\x03\x04") == 0;
  if (zip_magic || ends_with_ci(path, ".jpk-force")) return read_jpk_force(path, b, options);
  if (looks_like_afm_workshop_csv(b)) return read_afm_workshop_csv(path, b, options);
  if (looks_like_tab_export(b)) return read_tab_export(path, b, options);
  if (looks_like_ntmdt_txt(b)) return read_ntmdt_txt(path, b, options);
  return read_column_text(path, b, options);
}

}  // namespace cellflow::afm
