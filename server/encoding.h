// Byte encodings the server shares: base64url without padding (page tokens,
// API tokens) and SHA-256 as lowercase hex (stored token hashes, the names of
// uploaded meshes; OpenSSL libcrypto).
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace cellflow::server {

std::string base64url(std::string_view bytes);
// nullopt when `text` holds a character outside the alphabet.
std::optional<std::string> unbase64url(std::string_view text);

// 64 lowercase hex digits; empty if libcrypto fails.
std::string sha256_hex(std::string_view bytes);
bool is_sha256_hex(std::string_view text);

}  // namespace cellflow::server
