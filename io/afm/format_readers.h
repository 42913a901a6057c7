// One reader per instrument format, each over bytes already read by
// read_regular_file (so none of them touches the file system). The dispatch
// in read_force_curve.cc picks one; tests may call them directly.
#pragma once

#include <string>
#include <string_view>

#include "io/afm/force_curve.h"
#include "io/afm/read_options.h"
#include "physics/core/status.h"

namespace cellflow::afm {

// path is used for metadata and error messages only.
StatusOr<ForceCurve> read_jpk_force(const std::string& path, const std::string& bytes,
                                    const ReadOptions& options);
StatusOr<ForceCurve> read_afm_workshop_csv(const std::string& path, std::string_view text,
                                           const ReadOptions& options);
StatusOr<ForceCurve> read_ntmdt_txt(const std::string& path, std::string_view text,
                                    const ReadOptions& options);
StatusOr<ForceCurve> read_tab_export(const std::string& path, std::string_view text,
                                     const ReadOptions& options);
StatusOr<ForceCurve> read_column_text(const std::string& path, std::string_view text,
                                      const ReadOptions& options);

// Content sniffing used by the dispatch.
bool looks_like_afm_workshop_csv(std::string_view text);
bool looks_like_tab_export(std::string_view text);
bool looks_like_ntmdt_txt(std::string_view text);

}  // namespace cellflow::afm
