// See include/tabletop_shapes/core/pcd_reader.h.
#include "tabletop_shapes/core/pcd_reader.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <sstream>
#include <vector>

namespace tabletop_shapes {
namespace {

// A header longer than this is not a PCD header (PCL writes ~200 bytes).
constexpr size_t kMaxHeaderBytes = 64 * 1024;
// Bytes of one point: PCL's widest point types (e.g. FPFH descriptors) hold a few hundred.
constexpr uint64_t kMaxPointBytes = 64 * 1024;

struct Field {
  std::string name;
  uint32_t size = 0;    // bytes of one element: 1, 2, 4 or 8
  char type = 0;        // F, U or I
  uint32_t count = 1;   // elements
  uint64_t offset = 0;  // in a binary point
};

struct Header {
  std::vector<Field> fields;
  uint64_t width = 0, height = 1, points = 0;
  bool has_points = false, has_width = false;
  std::string data;
  size_t body_offset = 0;  // first byte after the DATA line
  uint64_t point_bytes = 0;
};

std::string str(uint64_t value) { return std::to_string(value); }

uint64_t parseCount(const std::string& keyword, const std::string& word) {
  if (word.empty() || word.find_first_not_of("0123456789") != std::string::npos ||
      word.size() > 18) {
    throw PcdError(keyword + " '" + word + "' is not a non-negative integer");
  }
  return std::stoull(word);
}

Header parseHeader(const uint8_t* data, size_t size) {
  Header header;
  std::vector<std::string> sizes, types, counts;
  size_t pos = 0;
  bool have_fields = false;
  while (true) {
    if (pos >= size || pos >= kMaxHeaderBytes) {
      throw PcdError(pos >= kMaxHeaderBytes ? "not a PCD header (no DATA line in the first 64 KiB)"
                                            : "not a PCD header (no DATA line)");
    }
    const uint8_t* end = static_cast<const uint8_t*>(
        std::memchr(data + pos, '\n', std::min(size, kMaxHeaderBytes) - pos));
    const size_t line_end = end ? static_cast<size_t>(end - data) : std::min(size, kMaxHeaderBytes);
    std::string line(reinterpret_cast<const char*>(data + pos), line_end - pos);
    pos = line_end + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    for (char c : line) {
      if (static_cast<unsigned char>(c) < 0x09 || static_cast<unsigned char>(c) > 0x7e) {
        throw PcdError("not a PCD header (binary bytes before the DATA line)");
      }
    }
    std::istringstream words(line);
    std::string keyword;
    if (!(words >> keyword) || keyword[0] == '#') continue;
    std::vector<std::string> values;
    for (std::string word; words >> word;) values.push_back(word);
    auto single = [&]() -> const std::string& {
      if (values.size() != 1) throw PcdError(keyword + " wants one value");
      return values[0];
    };
    if (keyword == "VERSION" || keyword == "VIEWPOINT") {
      continue;
    } else if (keyword == "FIELDS") {
      if (values.empty()) throw PcdError("FIELDS names no field");
      have_fields = true;
      for (const std::string& name : values) header.fields.push_back({name});
    } else if (keyword == "SIZE") {
      sizes = values;
    } else if (keyword == "TYPE") {
      types = values;
    } else if (keyword == "COUNT") {
      counts = values;
    } else if (keyword == "WIDTH") {
      header.width = parseCount(keyword, single());
      header.has_width = true;
    } else if (keyword == "HEIGHT") {
      header.height = parseCount(keyword, single());
    } else if (keyword == "POINTS") {
      header.points = parseCount(keyword, single());
      header.has_points = true;
    } else if (keyword == "DATA") {
      header.data = single();
      header.body_offset = std::min(pos, size);
      break;
    } else {
      throw PcdError("not a PCD header (unknown keyword '" + keyword.substr(0, 32) + "')");
    }
  }
  if (!have_fields) throw PcdError("no FIELDS line");
  if (header.data != "ascii" && header.data != "binary" && header.data != "binary_compressed") {
    throw PcdError("DATA '" + header.data.substr(0, 32) +
                   "' is not ascii, binary or binary_compressed");
  }
  const size_t n = header.fields.size();
  if (sizes.size() != n)
    throw PcdError("SIZE has " + str(sizes.size()) + " values for " + str(n) + " fields");
  if (types.size() != n)
    throw PcdError("TYPE has " + str(types.size()) + " values for " + str(n) + " fields");
  if (!counts.empty() && counts.size() != n) {
    throw PcdError("COUNT has " + str(counts.size()) + " values for " + str(n) + " fields");
  }
  for (size_t i = 0; i < n; ++i) {
    Field& f = header.fields[i];
    const uint64_t field_size = parseCount("SIZE", sizes[i]);
    if (field_size != 1 && field_size != 2 && field_size != 4 && field_size != 8) {
      throw PcdError("SIZE of field '" + f.name + "' is " + sizes[i] + ", not 1, 2, 4 or 8");
    }
    f.size = static_cast<uint32_t>(field_size);
    if (types[i] != "F" && types[i] != "U" && types[i] != "I") {
      throw PcdError("TYPE of field '" + f.name + "' is '" + types[i].substr(0, 8) +
                     "', not F, U or I");
    }
    f.type = types[i][0];
    if (f.type == 'F' && f.size != 4 && f.size != 8) {
      throw PcdError("field '" + f.name + "' is a float of " + sizes[i] + " bytes");
    }
    const uint64_t count = counts.empty() ? 1 : parseCount("COUNT", counts[i]);
    if (count < 1 || count > kMaxPointBytes) {
      throw PcdError("COUNT of field '" + f.name + "' is " + str(count));
    }
    f.count = static_cast<uint32_t>(count);
    f.offset = header.point_bytes;
    header.point_bytes += f.size * count;
    if (header.point_bytes > kMaxPointBytes) {
      throw PcdError("a point of more than " + str(kMaxPointBytes) + " bytes");
    }
  }
  if (!header.has_width) throw PcdError("no WIDTH line");
  if (!header.has_points) {
    if (header.height != 0 && header.width > std::numeric_limits<uint64_t>::max() / header.height) {
      throw PcdError("WIDTH x HEIGHT overflows");
    }
    header.points = header.width * header.height;
  }
  // width and height are each below 10^18: their product cannot overflow 128 bits, but can
  // overflow 64 bits; compare by division instead.
  if (header.height == 0
          ? header.points != 0 || header.width != 0
          : header.width != header.points / header.height || header.points % header.height != 0) {
    throw PcdError("WIDTH " + str(header.width) + " x HEIGHT " + str(header.height) +
                   " is not POINTS " + str(header.points));
  }
  return header;
}

// The x, y and z fields: one float32 or float64 element each.
struct XyzFields {
  const Field* axis[3];
};

XyzFields findXyz(const Header& header) {
  XyzFields xyz{};
  const char* names[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    for (const Field& f : header.fields) {
      if (f.name == names[a]) xyz.axis[a] = &f;
    }
    const Field* f = xyz.axis[a];
    if (!f) throw PcdError(std::string("no '") + names[a] + "' field");
    if (f->type != 'F' || f->count != 1) {
      throw PcdError(std::string("field '") + names[a] + "' is not one float (TYPE " + f->type +
                     ", SIZE " + str(f->size) + ", COUNT " + str(f->count) + ")");
    }
  }
  return xyz;
}

float readFloat(const uint8_t* at, uint32_t size) {
  if (size == 4) {
    float v;
    std::memcpy(&v, at, 4);
    return v;
  }
  double v;
  std::memcpy(&v, at, 8);
  return static_cast<float>(v);  // float64 x y z: metres fit a float
}

// Binary points, `stride` bytes apart; `field_base[a]` is where axis a of point 0 lies.
void readBinaryPoints(const uint8_t* const field_base[3], const uint64_t stride[3],
                      const XyzFields& xyz, pcl::PointCloud<pcl::PointXYZ>& cloud) {
  for (size_t i = 0; i < cloud.size(); ++i) {
    pcl::PointXYZ& p = cloud.points[i];
    for (int a = 0; a < 3; ++a) {
      p.data[a] = readFloat(field_base[a] + i * stride[a], xyz.axis[a]->size);
    }
  }
}

void readAscii(const uint8_t* body, size_t size, const Header& header, const XyzFields& xyz,
               pcl::PointCloud<pcl::PointXYZ>& cloud) {
  uint64_t values_per_point = 0;
  for (const Field& f : header.fields) values_per_point += f.count;
  // the value index of x, y, z within a line
  uint64_t index[3] = {0, 0, 0};
  for (int a = 0; a < 3; ++a) {
    for (const Field& f : header.fields) {
      if (&f == xyz.axis[a]) break;
      index[a] += f.count;
    }
  }
  size_t pos = 0, line_number = 0, point = 0;
  std::string token;
  while (pos < size) {
    const uint8_t* end = static_cast<const uint8_t*>(std::memchr(body + pos, '\n', size - pos));
    const size_t line_end = end ? static_cast<size_t>(end - body) : size;
    const char* line = reinterpret_cast<const char*>(body + pos);
    const size_t length = line_end - pos;
    pos = line_end + 1;
    ++line_number;
    size_t i = 0;
    uint64_t value = 0;
    auto where = [&] { return "data line " + str(line_number) + ": "; };
    while (true) {
      while (i < length && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
      if (i >= length) break;
      size_t j = i;
      while (j < length && line[j] != ' ' && line[j] != '\t' && line[j] != '\r') ++j;
      token.assign(line + i, j - i);
      i = j;
      char* parsed_end = nullptr;
      errno = 0;
      const double v = std::strtod(token.c_str(), &parsed_end);
      if (parsed_end != token.c_str() + token.size() || token.empty()) {
        throw PcdError(where() + "'" + token.substr(0, 32) + "' is not a number");
      }
      if (value >= values_per_point) {
        throw PcdError(where() + "more than the " + str(values_per_point) + " values a point has");
      }
      if (point < cloud.size()) {
        for (int a = 0; a < 3; ++a) {
          if (value == index[a]) cloud.points[point].data[a] = static_cast<float>(v);
        }
      }
      ++value;
    }
    if (value == 0) continue;  // a blank line
    if (value != values_per_point) {
      throw PcdError(where() + str(value) + " values, a point has " + str(values_per_point));
    }
    if (++point > cloud.size()) {
      throw PcdError("more points than POINTS " + str(header.points) + " declares");
    }
  }
  if (point != cloud.size()) {
    throw PcdError("POINTS " + str(header.points) + " declared, the data holds " + str(point));
  }
}

}  // namespace

bool lzfDecompressExact(const uint8_t* in, size_t in_size, uint8_t* out, size_t out_size) {
  size_t ip = 0, op = 0;
  while (ip < in_size) {
    const unsigned ctrl = in[ip++];
    if (ctrl < 32) {  // a literal run of ctrl + 1 bytes
      const size_t length = ctrl + 1;
      if (length > in_size - ip || length > out_size - op) return false;
      std::memcpy(out + op, in + ip, length);
      ip += length;
      op += length;
      continue;
    }
    size_t length = ctrl >> 5;  // a back reference of length + 2 bytes
    if (length == 7) {
      if (ip >= in_size) return false;
      length += in[ip++];
    }
    length += 2;
    if (ip >= in_size) return false;
    const size_t distance = ((ctrl & 0x1f) << 8) + in[ip++] + 1;
    if (distance > op || length > out_size - op) return false;
    for (size_t k = 0; k < length; ++k, ++op) out[op] = out[op - distance];  // may overlap
  }
  return op == out_size;
}

pcl::PointCloud<pcl::PointXYZ> parsePcd(const uint8_t* data, size_t size,
                                        const PcdReadOptions& options) {
  const Header header = parseHeader(data, size);
  if (header.points > options.max_points) {
    throw PcdError("POINTS " + str(header.points) + " is above the limit of " +
                   str(options.max_points) + " (--max-points)");
  }
  if (header.points > std::numeric_limits<uint64_t>::max() / kMaxPointBytes) {
    throw PcdError("POINTS " + str(header.points) + " is beyond any file");
  }
  const XyzFields xyz = findXyz(header);
  const uint8_t* body = data + header.body_offset;
  const size_t body_size = size - header.body_offset;
  const uint64_t data_bytes = header.points * header.point_bytes;  // both capped: no overflow

  pcl::PointCloud<pcl::PointXYZ> cloud;
  if (header.data == "binary") {
    if (body_size != data_bytes) {
      throw PcdError("binary data of " + str(body_size) + " bytes, but POINTS " +
                     str(header.points) + " x " + str(header.point_bytes) + " bytes = " +
                     str(data_bytes) + (body_size < data_bytes ? " (truncated)" : ""));
    }
    cloud.resize(header.points);
    const uint8_t* base[3];
    uint64_t stride[3];
    for (int a = 0; a < 3; ++a) {
      base[a] = body + xyz.axis[a]->offset;
      stride[a] = header.point_bytes;
    }
    readBinaryPoints(base, stride, xyz, cloud);
  } else if (header.data == "binary_compressed") {
    if (header.points == 0 && body_size == 0) {
      // PCL writes no block for an empty cloud
    } else {
      if (body_size < 8) throw PcdError("binary_compressed data without its size fields");
      uint32_t compressed = 0, uncompressed = 0;
      std::memcpy(&compressed, body, 4);
      std::memcpy(&uncompressed, body + 4, 4);
      if (uncompressed != data_bytes) {
        throw PcdError("compressed block decompresses to " + str(uncompressed) +
                       " bytes, but POINTS " + str(header.points) + " x " +
                       str(header.point_bytes) + " bytes = " + str(data_bytes));
      }
      if (compressed > body_size - 8) {
        throw PcdError("compressed block of " + str(compressed) + " bytes, the file holds " +
                       str(body_size - 8) + " (truncated)");
      }
      std::vector<uint8_t> raw(data_bytes);
      if (!lzfDecompressExact(body + 8, compressed, raw.data(), raw.size())) {
        throw PcdError("compressed block is corrupt (LZF data does not decompress to " +
                       str(data_bytes) + " bytes)");
      }
      // Column-major: all points' first field, then all points' second field, ...
      cloud.resize(header.points);
      const uint8_t* base[3];
      uint64_t stride[3];
      for (int a = 0; a < 3; ++a) {
        base[a] = raw.data() + xyz.axis[a]->offset * header.points;
        stride[a] = xyz.axis[a]->size;
      }
      readBinaryPoints(base, stride, xyz, cloud);
    }
  } else {
    // Each value takes at least a digit and a separator: a body too short for the declared
    // points is refused before the cloud is allocated.
    uint64_t values_per_point = 0;
    for (const Field& f : header.fields) values_per_point += f.count;
    if ((body_size + 1) / 2 / values_per_point < header.points) {
      throw PcdError("ascii data of " + str(body_size) + " bytes cannot hold POINTS " +
                     str(header.points) + " (truncated)");
    }
    cloud.resize(header.points);
    readAscii(body, body_size, header, xyz, cloud);
  }
  cloud.width = static_cast<uint32_t>(header.width);
  cloud.height = static_cast<uint32_t>(header.height);
  if (header.points == 0) cloud.width = 0, cloud.height = header.height == 0 ? 0 : 1;
  cloud.is_dense = true;
  for (const pcl::PointXYZ& p : cloud.points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      cloud.is_dense = false;
      break;
    }
  }
  return cloud;
}

pcl::PointCloud<pcl::PointXYZ> readPcdFile(const std::string& path, const PcdReadOptions& options) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw PcdError(std::strerror(errno));
  struct stat st;
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw PcdError("not a regular file");
  }
  const size_t size = static_cast<size_t>(st.st_size);
  if (size == 0) {
    ::close(fd);
    throw PcdError("empty file");
  }
  void* mapped = ::mmap(nullptr, size, PROT_READ, MAP_PRIVATE, fd, 0);
  ::close(fd);
  if (mapped == MAP_FAILED) throw PcdError(std::string("cannot map: ") + std::strerror(errno));
  try {
    pcl::PointCloud<pcl::PointXYZ> cloud =
        parsePcd(static_cast<const uint8_t*>(mapped), size, options);
    ::munmap(mapped, size);
    return cloud;
  } catch (...) {
    ::munmap(mapped, size);
    throw;
  }
}

}  // namespace tabletop_shapes
