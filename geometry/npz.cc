#include "geometry/npz.h"

#include <unistd.h>
#include <zip.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <regex>
#include <unordered_map>

#include "geometry/util/input_file.h"
#include "geometry/util/size_limits.h"
#include "geometry/util/status.h"

namespace geodrive {

struct NpzReader::Impl {
  std::string path;
  zip_t* archive = nullptr;
  std::vector<std::string> keys;
  // Member index and uncompressed size of each key (checked on opening).
  struct Member {
    zip_uint64_t index = 0;
    uint64_t size = 0;
  };
  std::unordered_map<std::string, Member> members;

  ~Impl() {
    if (archive) zip_discard(archive);  // read-only: nothing to write back
  }

  const Member& MemberOf(const std::string& key) const {
    const auto it = members.find(key);
    if (it == members.end()) {
      std::string have;
      for (size_t i = 0; i < keys.size() && i < 20; ++i)
        have += (have.empty() ? "" : ", ") + keys[i];
      if (keys.size() > 20)
        have += ", ... (" + std::to_string(keys.size()) + ")";
      ThrowInputError(path, "no array '", key, "' (it has: ", have, ")");
    }
    return it->second;
  }

  std::string What(const std::string& key) const {
    return path + ": " + key + ".npy";
  }

  // Reads up to `limit` bytes of member `key` (all of it by default), checking
  // the size libzip reports and, for whole reads, the CRC.
  // The member's size was checked against its compressed bytes, the file and
  // the limits when the archive was opened (CheckMembers).
  std::vector<uint8_t> ReadMember(const std::string& key,
                                  uint64_t limit) const {
    const Member& member = MemberOf(key);
    const zip_uint64_t i = member.index;
    zip_stat_t st;
    zip_stat_init(&st);
    st.size = member.size;
    const uint64_t want = std::min<uint64_t>(st.size, limit);
    zip_file_t* file = zip_fopen_index(archive, i, 0);
    if (!file) {
      ThrowInputError(What(key),
                      "cannot open the member: ", zip_strerror(archive));
    }
    std::vector<uint8_t> bytes(want);
    uint64_t got = 0;
    while (got < want) {
      const zip_int64_t n = zip_fread(file, bytes.data() + got,
                                      static_cast<zip_uint64_t>(want - got));
      if (n <= 0) {
        const std::string why =
            n < 0 ? zip_file_strerror(file) : "member ends early";
        zip_fclose(file);
        ThrowInputError(What(key), "damaged member (", why, ") after ", got,
                        " of ", st.size, " bytes");
      }
      got += static_cast<uint64_t>(n);
    }
    // A whole read: libzip checks the CRC when the member is read to its end
    // (one more read returns 0, or an error on mismatch).
    if (want == st.size) {
      uint8_t extra;
      const zip_int64_t n = zip_fread(file, &extra, 1);
      if (n != 0) {
        const std::string why =
            n < 0 ? zip_file_strerror(file) : "more data than declared";
        zip_fclose(file);
        ThrowInputError(What(key), "damaged member: ", why);
      }
    }
    zip_fclose(file);
    return bytes;
  }
};

NpzReader::NpzReader(const std::string& path) : impl_(new Impl) {
  impl_->path = path;
  CheckInputFile(path);  // libzip opens the path itself
  int error = 0;
  impl_->archive = zip_open(path.c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &error);
  if (!impl_->archive) {
    zip_error_t e;
    zip_error_init_with_code(&e, error);
    const std::string why = zip_error_strerror(&e);
    zip_error_fini(&e);
    ThrowInputError(path, "not a readable .npz (zip) archive: ", why);
  }
  // Every declared size is checked before any member is inflated: the
  // member count, each member's size against its compressed bytes (the
  // ratio) and the limit, the compressed bytes together against the file (no
  // two entries share data), the sizes together against the archive limit.
  const zip_int64_t n = zip_get_num_entries(impl_->archive, 0);
  CheckDeclaredCount(path, "the archive", static_cast<uint64_t>(n),
                     SizeLimits::kMaxArchiveMembers);
  const uint64_t file_size = CheckInputFile(path);
  uint64_t compressed_total = 0, uncompressed_total = 0;
  impl_->keys.reserve(static_cast<size_t>(n));
  impl_->members.reserve(static_cast<size_t>(n));
  for (zip_int64_t i = 0; i < n; ++i) {
    const zip_uint64_t index = static_cast<zip_uint64_t>(i);
    zip_stat_t st;
    zip_stat_init(&st);
    if (zip_stat_index(impl_->archive, index, 0, &st) != 0 || !st.name ||
        !(st.valid & ZIP_STAT_SIZE) || !(st.valid & ZIP_STAT_COMP_SIZE)) {
      ThrowInputError(path, "cannot read the sizes of member ", i, ": ",
                      zip_strerror(impl_->archive));
    }
    const std::string name = st.name;
    const std::string member = "member '" + name + "'";
    CheckDeclaredSize(path, member + " (compressed)", st.comp_size,
                      file_size - compressed_total, file_size);
    compressed_total += st.comp_size;
    CheckDeclaredSize(path, member, st.size, SizeLimits::kMaxMemberBytes,
                      SizeLimits::kMaxMemberBytes);
    if ((st.valid & ZIP_STAT_COMP_METHOD) && st.comp_method == ZIP_CM_STORE) {
      GEODRIVE_CHECK_INPUT(st.size == st.comp_size, path, ": stored ", member,
                           " declares ", st.size, " bytes but holds ",
                           st.comp_size);
    }
    CheckCompressionRatio(path, member, st.size, st.comp_size);
    uncompressed_total += st.size;
    CheckDeclaredSize(path, "the archive", uncompressed_total,
                      SizeLimits::kMaxArchiveBytes,
                      SizeLimits::kMaxArchiveBytes);
    std::string key = name;
    if (key.size() > 4 && key.compare(key.size() - 4, 4, ".npy") == 0)
      key.resize(key.size() - 4);
    const bool added =
        impl_->members.emplace(key, Impl::Member{index, st.size}).second;
    GEODRIVE_CHECK_INPUT(added, path, ": member '", name, "' appears twice");
    impl_->keys.push_back(key);
  }
}

NpzReader::~NpzReader() = default;

const std::string& NpzReader::path() const { return impl_->path; }

const std::vector<std::string>& NpzReader::Keys() const { return impl_->keys; }

bool NpzReader::Has(const std::string& key) const {
  return impl_->members.count(key) != 0;
}

NpyHeader NpzReader::Header(const std::string& key) const {
  // The preamble (12 bytes) plus the largest header ParseNpyHeader accepts.
  const std::vector<uint8_t> head = impl_->ReadMember(key, 12 + 65536);
  return ParseNpyHeader(impl_->What(key), head.data(), head.size());
}

NpyArray NpzReader::Read(const std::string& key,
                         const NpyReadOptions& options) const {
  // Header first: the declared array must fit the limit before the member
  // is decompressed into memory.
  const NpyHeader header = Header(key);
  const uint64_t declared = SaturatingMul(
      static_cast<uint64_t>(header.NumElements()), NpyDtypeSize(header.dtype));
  if (declared > options.max_bytes) {
    ThrowInputError(impl_->What(key), "array of ", declared,
                    " bytes exceeds the limit of ", options.max_bytes,
                    " bytes");
  }
  // The shape must fit the member's own (checked) size: a header declaring
  // more than the member holds is refused before the member is inflated.
  const uint64_t member_size = impl_->MemberOf(key).size;
  const uint64_t data_size =
      member_size > header.data_offset ? member_size - header.data_offset : 0;
  CheckDeclaredSize(impl_->What(key), "the array", declared, data_size,
                    options.max_bytes);
  return ParseNpy(impl_->What(key),
                  impl_->ReadMember(key, header.data_offset + declared),
                  options);
}

NpyArray NpzReader::ReadAsFloat32(const std::string& key,
                                  const NpyReadOptions& options) const {
  return ConvertNpyToFloat32(Read(key, options));
}

std::string NpzReader::ReadString(const std::string& key) const {
  // numpy.lib.format: magic (6), version (2), header length (2 or 4), then
  // the header dict, e.g. {'descr': '<U6', 'fortran_order': False,
  // 'shape': (), }. The dtype parser of npy.cc knows numeric dtypes only.
  const std::string what = impl_->What(key);
  const std::vector<uint8_t> head = impl_->ReadMember(key, 12 + 4096);
  GEODRIVE_CHECK_INPUT(head.size() >= 10 && head[0] == 0x93 &&
                           std::memcmp(head.data() + 1, "NUMPY", 5) == 0,
                       what, ": not a .npy member");
  const int major = head[6];
  const size_t len_bytes = major == 1 ? 2 : 4;
  GEODRIVE_CHECK_INPUT(head.size() >= 8 + len_bytes, what,
                       ": truncated header");
  size_t header_len = 0;
  for (size_t i = 0; i < len_bytes; ++i)
    header_len |= static_cast<size_t>(head[8 + i]) << (8 * i);
  const size_t start = 8 + len_bytes;
  GEODRIVE_CHECK_INPUT(header_len <= 4096 && start + header_len <= head.size(),
                       what, ": header of ", header_len,
                       " bytes is longer than a string scalar's");
  const std::string dict(reinterpret_cast<const char*>(head.data()) + start,
                         header_len);
  std::smatch m;
  static const std::regex kDescr(R"('descr'\s*:\s*'([<>|=])([US])(\d{1,4})')");
  static const std::regex kShape(R"('shape'\s*:\s*\((1,)?\))");
  GEODRIVE_CHECK_INPUT(std::regex_search(dict, m, kDescr), what,
                       ": not a string (expected a str such as "
                       "units=\"metres\"; header ",
                       dict.substr(0, 60), ")");
  const bool unicode = m[2].str() == "U";
  const bool big = m[1].str() == ">";
  const size_t chars = std::stoul(m[3].str());
  GEODRIVE_CHECK_INPUT(std::regex_search(dict, kShape), what,
                       ": a string scalar must have shape () or (1,)");
  const size_t bytes = chars * (unicode ? 4 : 1);
  const std::vector<uint8_t> all =
      impl_->ReadMember(key, start + header_len + bytes);
  GEODRIVE_CHECK_INPUT(all.size() == start + header_len + bytes, what,
                       ": string data ends early");
  std::string out;
  for (size_t c = 0; c < chars; ++c) {
    uint32_t code = 0;
    if (unicode) {
      const uint8_t* p = all.data() + start + header_len + 4 * c;
      code = big ? (uint32_t{p[0]} << 24 | uint32_t{p[1]} << 16 |
                    uint32_t{p[2]} << 8 | p[3])
                 : (uint32_t{p[3]} << 24 | uint32_t{p[2]} << 16 |
                    uint32_t{p[1]} << 8 | p[0]);
    } else {
      code = all[start + header_len + c];
    }
    if (code == 0) break;  // numpy pads with NULs
    GEODRIVE_CHECK_INPUT(code < 128 && code >= 32, what,
                         ": non-ASCII character in the string");
    out.push_back(static_cast<char>(code));
  }
  return out;
}

namespace {

// One member of an archive being written: its name (with ".npy") and its
// bytes as fragments held by the caller.
struct ZipMember {
  std::string name;
  std::vector<zip_buffer_fragment_t> fragments;
};

// Writes `members` as a zip archive at `path` (temporary file + rename),
// deflated or stored, every member dated 1980-01-02. libzip only reads the
// fragments.
void WriteZipMembers(const std::string& path,
                     std::vector<ZipMember>& members,
                     bool compress) {
  const std::string tmp = path + ".tmp-npz";
  int error = 0;
  zip_t* z = zip_open(tmp.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error);
  GEODRIVE_CHECK_INPUT(z != nullptr, path, ": cannot create the archive");
  for (ZipMember& m : members) {
    zip_source_t* src = zip_source_buffer_fragment(
        z, m.fragments.data(), m.fragments.size(), /*freep=*/0);
    const zip_int64_t index =
        src ? zip_file_add(z, m.name.c_str(), src, ZIP_FL_ENC_UTF_8) : -1;
    if (index < 0) {
      if (src) zip_source_free(src);
      const std::string why = zip_strerror(z);
      zip_discard(z);
      std::remove(tmp.c_str());
      ThrowInputError(path, "cannot add member ", m.name, ": ", why);
    }
    zip_set_file_compression(z, static_cast<zip_uint64_t>(index),
                             compress ? ZIP_CM_DEFLATE : ZIP_CM_STORE, 0);
    // A fixed member time (1980-01-02: after the zip format's 1980 epoch in
    // every time zone): the same arrays give the same bytes.
    zip_file_set_mtime(z, static_cast<zip_uint64_t>(index), 315619200, 0);
  }
  if (zip_close(z) != 0) {
    const std::string why = zip_strerror(z);
    zip_discard(z);
    std::remove(tmp.c_str());
    ThrowInputError(path, "cannot write the archive: ", why);
  }
  GEODRIVE_CHECK_INPUT(std::rename(tmp.c_str(), path.c_str()) == 0, path,
                       ": cannot rename the temporary archive into place");
}

zip_buffer_fragment_t Fragment(const void* data, size_t size) {
  return {const_cast<zip_uint8_t*>(static_cast<const zip_uint8_t*>(data)),
          size};
}

}  // namespace

namespace {

// One .npy member given as its header (or its whole file) and the data's
// pieces after it.
struct NpyMember {
  std::string name;  // without ".npy"
  std::string head;
  std::vector<std::pair<const void*, size_t>> pieces;
};

void WriteNpyMembers(const std::string& path,
                     const std::vector<NpyMember>& npy,
                     bool compress) {
  std::vector<ZipMember> members(npy.size());
  for (size_t i = 0; i < npy.size(); ++i) {
    members[i].name = npy[i].name + ".npy";
    members[i].fragments.push_back(
        Fragment(npy[i].head.data(), npy[i].head.size()));
    for (const auto& [data, size] : npy[i].pieces) {
      if (size > 0) members[i].fragments.push_back(Fragment(data, size));
    }
  }
  WriteZipMembers(path, members, compress);
}

}  // namespace

void WriteNpz(const std::string& path,
              const std::vector<std::pair<std::string, NpyArray>>& arrays,
              bool compress) {
  // Each member is the .npy file (format 1.0) WriteNpy would write: its
  // header, then the array's own bytes where they are stored as they are
  // (no copy of the data), else the whole file built in memory.
  std::vector<NpyMember> members;
  for (const auto& [name, array] : arrays) {
    const std::string what = path + ":" + name;
    NpyMember m{name, {}, {}};
    if (NpyDataIsStoredAsIs(array)) {
      m.head = NpyFileHeader(what, array);
      m.pieces.emplace_back(array.bytes.data(), array.bytes.size());
    } else {
      m.head = SerializeNpy(what, array);
    }
    members.push_back(std::move(m));
  }
  WriteNpyMembers(path, members, compress);
}

void WriteNpz(const std::string& path,
              const std::vector<std::pair<std::string, NpyPieces>>& arrays,
              bool compress) {
  std::vector<NpyMember> members;
  for (const auto& [name, array] : arrays) {
    const std::string what = path + ":" + name;
    NpyMember m{name, NpyFileHeader(what, array.dtype, array.shape),
                array.pieces};
    uint64_t held = 0;
    for (const auto& [data, size] : array.pieces) held += size;
    uint64_t count = 1;
    for (const int64_t d : array.shape) count *= static_cast<uint64_t>(d);
    const uint64_t needed = count * NpyDtypeSize(array.dtype);
    GEODRIVE_CHECK_INPUT(held == needed, what, ": the pieces hold ", held,
                         " bytes but the shape needs ", needed);
    members.push_back(std::move(m));
  }
  WriteNpyMembers(path, members, compress);
}

bool LooksLikeZip(const std::string& path) {
  char magic[4] = {0, 0, 0, 0};
  try {
    const InputFile in = OpenInputFile(path);  // false for a folder or FIFO
    if (::pread(in.fd(), magic, 4, 0) != 4) return false;
  } catch (const InputError&) {
    return false;
  }
  return std::memcmp(magic, "PK\x03\x04", 4) == 0;
}

}  // namespace geodrive
