// A real JPK archive with one entry rewritten: the reader must notice that the
// channel data no longer fits the declared point count, or that a channel
// entry is missing, and say which entry.
#include <gtest/gtest.h>
#include <unistd.h>
#include <zip.h>

#include <filesystem>
#include <string>

#include "afm_test_util.h"
#include "io/afm/read_force_curve.h"

namespace cellflow::afm {
namespace {

namespace fs = std::filesystem;

// Copies spot3 to a temp file and replaces (or deletes, if content is empty)
// one entry.
std::string tampered_copy(const std::string& tag, const std::string& entry, const std::string& content) {
  const fs::path p =
      fs::temp_directory_path() / ("afm-tamper-" + tag + "-" + std::to_string(::getpid()) + ".jpk-force");
  fs::copy_file(testing::data_file("fmt-jpk-fd_spot3-0192.jpk-force"), p,
                fs::copy_options::overwrite_existing);
  fs::permissions(p, fs::perms::owner_read | fs::perms::owner_write);
  int err = 0;
  zip_t* z = zip_open(p.c_str(), 0, &err);
  EXPECT_NE(z, nullptr);
  const zip_int64_t idx = zip_name_locate(z, entry.c_str(), 0);
  EXPECT_GE(idx, 0);
  if (content.empty()) {
    zip_delete(z, static_cast<zip_uint64_t>(idx));
  } else {
    // libzip copies the buffer at zip_close (freep = 0: we own it until then).
    zip_source_t* src = zip_source_buffer(z, content.data(), content.size(), 0);
    zip_file_replace(z, static_cast<zip_uint64_t>(idx), src, 0);
  }
  EXPECT_EQ(zip_close(z), 0);
  return p.string();
}

std::string entry_text(const std::string& entry) {
  int err = 0;
  zip_t* z = zip_open(testing::data_file("fmt-jpk-fd_spot3-0192.jpk-force").c_str(), ZIP_RDONLY, &err);
  zip_stat_t st;
  zip_stat(z, entry.c_str(), 0, &st);
  std::string out(st.size, '\0');
  zip_file_t* f = zip_fopen(z, entry.c_str(), 0);
  zip_fread(f, out.data(), st.size);
  zip_fclose(f);
  zip_discard(z);
  return out;
}

TEST(AfmJpkTamper, ChannelShorterThanDeclaredPointCount) {
  std::string header = entry_text("segments/0/segment-header.properties");
  const std::string from = "force-segment-header.num-points=2000";
  const auto at = header.find(from);
  ASSERT_NE(at, std::string::npos);
  header.replace(at, from.size(), "force-segment-header.num-points=2001");
  const std::string p = tampered_copy("points", "segments/0/segment-header.properties", header);
  auto r = read_force_curve(p);
  fs::remove(p);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("segments/0/channels/"), std::string::npos) << r.status().message();
  EXPECT_NE(r.status().message().find("2001 points"), std::string::npos) << r.status().message();
}

TEST(AfmJpkTamper, MissingChannelEntry) {
  const std::string p = tampered_copy("missing", "segments/1/channels/vDeflection.dat", "");
  auto r = read_force_curve(p);
  fs::remove(p);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("segments/1/channels/vDeflection.dat"), std::string::npos)
      << r.status().message();
}

TEST(AfmJpkTamper, OddByteCountForShortData) {
  const std::string p =
      tampered_copy("odd", "segments/0/channels/strainGaugeHeight.dat", std::string(3999, '\x01'));
  auto r = read_force_curve(p);
  fs::remove(p);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("3999 bytes"), std::string::npos) << r.status().message();
}

}  // namespace
}  // namespace cellflow::afm
