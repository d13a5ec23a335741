#include "geometry/npz.h"

#include <zip.h>

#include <algorithm>
#include <cstring>
#include <fstream>

#include "geometry/util/status.h"

namespace geodrive {

struct NpzReader::Impl {
  std::string path;
  zip_t* archive = nullptr;
  std::vector<std::string> keys;
  std::vector<zip_uint64_t> index;  // member index of each key

  ~Impl() {
    if (archive) zip_discard(archive);  // read-only: nothing to write back
  }

  zip_uint64_t MemberOf(const std::string& key) const {
    const auto it = std::find(keys.begin(), keys.end(), key);
    if (it == keys.end()) {
      std::string have;
      for (const std::string& k : keys) have += (have.empty() ? "" : ", ") + k;
      ThrowInputError(path, "no array '", key, "' (it has: ", have, ")");
    }
    return index[static_cast<size_t>(it - keys.begin())];
  }

  std::string What(const std::string& key) const {
    return path + ": " + key + ".npy";
  }

  // Reads up to `limit` bytes of member `key` (all of it by default), checking
  // the size libzip reports and, for whole reads, the CRC.
  std::vector<uint8_t> ReadMember(const std::string& key,
                                  uint64_t limit) const {
    const zip_uint64_t i = MemberOf(key);
    zip_stat_t st;
    zip_stat_init(&st);
    if (zip_stat_index(archive, i, 0, &st) != 0 ||
        !(st.valid & ZIP_STAT_SIZE)) {
      ThrowInputError(What(key),
                      "cannot read the member's size: ", zip_strerror(archive));
    }
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
  int error = 0;
  impl_->archive = zip_open(path.c_str(), ZIP_RDONLY | ZIP_CHECKCONS, &error);
  if (!impl_->archive) {
    zip_error_t e;
    zip_error_init_with_code(&e, error);
    const std::string why = zip_error_strerror(&e);
    zip_error_fini(&e);
    ThrowInputError(path, "not a readable .npz (zip) archive: ", why);
  }
  const zip_int64_t n = zip_get_num_entries(impl_->archive, 0);
  for (zip_int64_t i = 0; i < n; ++i) {
    const char* name =
        zip_get_name(impl_->archive, static_cast<zip_uint64_t>(i), 0);
    if (!name) continue;
    std::string key = name;
    if (key.size() > 4 && key.compare(key.size() - 4, 4, ".npy") == 0)
      key.resize(key.size() - 4);
    GEODRIVE_CHECK_INPUT(std::find(impl_->keys.begin(), impl_->keys.end(),
                                   key) == impl_->keys.end(),
                         path, ": member '", name, "' appears twice");
    impl_->keys.push_back(key);
    impl_->index.push_back(static_cast<zip_uint64_t>(i));
  }
}

NpzReader::~NpzReader() = default;

const std::string& NpzReader::path() const { return impl_->path; }

const std::vector<std::string>& NpzReader::Keys() const { return impl_->keys; }

bool NpzReader::Has(const std::string& key) const {
  return std::find(impl_->keys.begin(), impl_->keys.end(), key) !=
         impl_->keys.end();
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
  const uint64_t declared =
      static_cast<uint64_t>(header.NumElements()) * NpyDtypeSize(header.dtype);
  if (declared > options.max_bytes) {
    ThrowInputError(impl_->What(key), "array of ", declared,
                    " bytes exceeds the limit of ", options.max_bytes,
                    " bytes");
  }
  const std::vector<uint8_t> bytes =
      impl_->ReadMember(key, header.data_offset + declared);
  return ParseNpy(impl_->What(key), bytes.data(), bytes.size(), options);
}

NpyArray NpzReader::ReadAsFloat32(const std::string& key,
                                  const NpyReadOptions& options) const {
  return ConvertNpyToFloat32(Read(key, options));
}

bool LooksLikeZip(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[4] = {0, 0, 0, 0};
  in.read(magic, 4);
  return in.gcount() == 4 && std::memcmp(magic, "PK\x03\x04", 4) == 0;
}

}  // namespace geodrive
