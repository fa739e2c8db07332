// Little-endian values in byte buffers: what the binary formats written and
// read here (PLY binary_little_endian, LAS) store, on a host of either order.
#pragma once

#include <algorithm>
#include <bit>
#include <cstring>
#include <string>

namespace treecut::detail {

/// Appends VALUE's bytes, least significant first.
template <class T>
void put_le(std::string& out, T value) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if constexpr (std::endian::native == std::endian::big) std::reverse(bytes, bytes + sizeof(T));
  out.append(bytes, sizeof(T));
}

/// The T stored least significant byte first at P.
template <class T>
T get_le(const unsigned char* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  if constexpr (std::endian::native == std::endian::big) {
    auto* b = reinterpret_cast<unsigned char*>(&v);
    std::reverse(b, b + sizeof v);
  }
  return v;
}

}  // namespace treecut::detail
