// Fuzz targets of the file formats in io/: .npy, PLY (standard and compressed), safetensors,
// .pth (zip and legacy stream), the restricted pickle alone, COLMAP binary and text models,
// images and masks.
#include <zip.h>

#include <fmt/format.h>

#include "common/error.h"
#include "fuzz_target.h"
#include "io/byte_reader.h"
#include "io/colmap.h"
#include "io/image.h"
#include "io/npy.h"
#include "io/pickle.h"
#include "io/ply.h"
#include "io/sog.h"
#include "io/spz.h"
#include "io/pth.h"
#include "io/reconstruct_checkpoint.h"
#include "io/safetensors.h"

namespace ii::fuzz {
namespace {

namespace fs = std::filesystem;
using namespace std::string_literals;  // byte strings below hold NULs

template <typename T>
void put(std::string& out, T v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

// ---- .npy ---------------------------------------------------------------------------------

const bool npy = register_target({
    "npy",
    [] {
      std::vector<std::string> seeds;
      seeds.push_back(bytes_written_by([](const fs::path& p) { write_npy(p, {1, 2, 3, 4, 5, 6}, {2, 3}); }));
      seeds.push_back(bytes_written_by([](const fs::path& p) { write_npy(p, {7}, {}); }));
      NpyArray bytes{"u1", {4}, {0, 1, 2, 255}};
      seeds.push_back(bytes_written_by([&](const fs::path& p) { write_npy(p, bytes); }));
      // Fortran order and a version-2 header, written by hand.
      std::string header = "{'descr': '<i2', 'fortran_order': True, 'shape': (2, 2), }";
      header.resize(118, ' ');
      header += '\n';
      std::string f = std::string("\x93NUMPY\x02\x00", 8);
      put<uint32_t>(f, static_cast<uint32_t>(header.size()));
      f += header;
      for (int16_t v : {1, 2, 3, 4}) put(f, v);
      seeds.push_back(f);
      return seeds;
    },
    [](const uint8_t* data, size_t size) {
      const fs::path path = scratch_dir() / "input.npy";
      write_file(path, data, size);
      const NpyArray a = read_npy(path);
      a.as_double();
    }});

// ---- PLY ----------------------------------------------------------------------------------

// Two splats with `rest` SH coefficients per channel: what the splat writers make seeds of.
SplatCloud two_splats(int rest) {
  SplatCloud c;
  c.means = {0, 1, 2, 3, 4, 5};
  c.normals.assign(6, 0.f);
  c.sh_dc = {0.1f, 0.2f, 0.3f, -0.1f, -0.2f, -0.3f};
  c.sh_rest_per_channel = rest;
  c.sh_rest.assign(6 * rest, 0.05f);
  c.opacity_logit = {0.5f, -1.f};
  c.log_scales = {-3, -3, -3, -2, -2, -2};
  c.rotations = {1, 0, 0, 0, 0.5f, 0.5f, 0.5f, 0.5f};
  return c;
}

const bool ply = register_target({
    "ply",
    [] {
      std::vector<std::string> seeds;
      const SplatCloud c = two_splats(3);
      seeds.push_back(bytes_written_by([&](const fs::path& p) { write_splat_ply(p, c); }));
      seeds.push_back(bytes_written_by([&](const fs::path& p) { write_compressed_splat_ply(p, c); }));
      seeds.push_back(
          "ply\nformat ascii 1.0\nelement vertex 1\nproperty float y\nproperty float x\nproperty float z\n"
          "property uchar red\nproperty float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\n"
          "property float opacity\nproperty float scale_0\nproperty float scale_1\nproperty float scale_2\n"
          "property float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\n"
          "element face 0\nproperty list uchar int vertex_indices\nend_header\n"
          "1 2 3 255 0.1 0.2 0.3 0 -2 -2 -2 1 0 0 0\n");
      // SuperSplat compressed: one chunk (18 float ranges) and three packed splats with SH.
      std::string z =
          "ply\nformat binary_little_endian 1.0\nelement chunk 1\n";
      for (const char* n : {"min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x", "min_scale_y",
                            "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z", "min_r", "min_g", "min_b",
                            "max_r", "max_g", "max_b"})
        z += fmt::format("property float {}\n", n);
      z += "element vertex 3\n";
      for (const char* n : {"packed_position", "packed_rotation", "packed_scale", "packed_color"})
        z += fmt::format("property uint {}\n", n);
      z += "element sh 3\n";
      for (int j = 0; j < 9; ++j) z += fmt::format("property uchar f_rest_{}\n", j);
      z += "end_header\n";
      for (float v : {0.f, 0.f, 0.f, 1.f, 1.f, 1.f, -5.f, -5.f, -5.f, -1.f, -1.f, -1.f, 0.f, 0.f, 0.f, 1.f, 1.f, 1.f})
        put(z, v);
      for (uint32_t i = 0; i < 3; ++i)
        for (uint32_t word : {(i << 21) | (1023u << 11) | 512u, (0u << 30) | (512u << 20) | (512u << 10) | 512u,
                              (2047u << 21) | 1024u, 0xff8000ffu - i})
          put(z, word);
      for (int k = 0; k < 27; ++k) z += static_cast<char>(k * 9);
      seeds.push_back(z);
      return seeds;
    },
    [](const uint8_t* data, size_t size) {
      const fs::path path = scratch_dir() / "input.ply";
      write_file(path, data, size);
      read_splat_ply(path);
    }});

// ---- SPZ ----------------------------------------------------------------------------------

const bool spz = register_target({
    "spz",
    [] {
      // Written by the project (version 3, gzip), degrees 0 and 1.
      std::vector<std::string> seeds;
      for (int rest : {0, 3}) {
        const SplatCloud c = two_splats(rest);
        seeds.push_back(bytes_written_by([&](const fs::path& p) { write_spz(p, c); }));
      }
      return seeds;
    },
    [](const uint8_t* data, size_t size) { decode_spz(data, size, "input.spz"); }});

// ---- SOG ----------------------------------------------------------------------------------

const bool sog = register_target({
    "sog",
    [] {
      // Written by the project: a bundle without and with an SH palette.
      std::vector<std::string> seeds;
      for (int rest : {0, 3}) {
        const SplatCloud c = two_splats(rest);
        seeds.push_back(bytes_written_by([&](const fs::path& p) { write_sog(p, c); }));
      }
      return seeds;
    },
    [](const uint8_t* data, size_t size) {
      const fs::path path = scratch_dir() / "input.sog";
      write_file(path, data, size);
      read_sog(path);
    }});

// ---- safetensors ----------------------------------------------------------------------------

const bool safetensors = register_target({
    "safetensors",
    [] {
      std::vector<std::pair<std::string, TensorData>> tensors;
      TensorData f32{"F32", {2, 2}, {}};
      for (float v : {1.f, -2.f, 3.5f, 0.f}) f32.bytes.insert(f32.bytes.end(), reinterpret_cast<uint8_t*>(&v),
                                                               reinterpret_cast<uint8_t*>(&v) + 4);
      tensors.emplace_back("a.weight", f32);
      tensors.emplace_back("b", TensorData{"BF16", {3}, {0, 0x3f, 0x80, 0x3f, 0, 0xc0}});
      tensors.emplace_back("c", TensorData{"BOOL", {}, {1}});
      tensors.emplace_back("empty", TensorData{"I64", {0, 4}, {}});
      return std::vector<std::string>{bytes_written_by([&](const fs::path& p) {
        write_safetensors(p, tensors, {{"format", "pt"}, {"step", "12"}});
      })};
    },
    [](const uint8_t* data, size_t size) {
      const SafetensorsFile f = parse_safetensors(data, size, "input.safetensors");
      for (const auto& [name, tensor] : f.tensors) tensor.to_float();
    }});

// ---- pickle and .pth ----------------------------------------------------------------------

std::string u32(uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); }
std::string pickle_string(const std::string& s) { return "X" + u32(static_cast<uint32_t>(s.size())) + s; }

std::string float_bytes(std::initializer_list<float> values) {
  std::string s;
  for (float v : values) put(s, v);
  return s;
}

// {"w": <float tensor 2x2 from storage "0">, "epoch": 3, "args": Namespace(lr=0.5)} as
// torch.save pickles it (protocol 2); the legacy stream's storage ids have a sixth item.
std::string checkpoint_pickle(bool legacy) {
  std::string p = "\x80\x02}q\x00("s;
  p += pickle_string("w");
  p += "ctorch._utils\n_rebuild_tensor_v2\nq\x01(";
  p += "(" + pickle_string("storage") + "ctorch\nFloatStorage\nq\x02" + pickle_string("0") + pickle_string("cpu") +
       "K\x04" + (legacy ? "N" : "") + "tq\x03Q";              // persistent id, BINPERSID
  p += "K\x00K\x02K\x02\x86q\x04K\x02K\x01\x86q\x05\x89"s;  // offset, shape, stride, requires_grad
  p += "ccollections\nOrderedDict\nq\x06)Rq\x07tq\x08Rq\x09";
  p += pickle_string("epoch") + "K\x03";
  p += pickle_string("args") + "cargparse\nNamespace\nq\x0a)\x81q\x0b}q\x0c" + pickle_string("lr") +
       "G?\xe0\x00\x00\x00\x00\x00\x00sb"s;
  p += "u.";
  return p;
}

// torch.save's stream before 1.6: magic, protocol and system-info pickles, the main pickle,
// the storage keys, then each storage as an int64 count and its data.
std::string legacy_checkpoint() {
  std::string f = "\x80\x02\x8a\x0a\x6c\xfc\x9c\x46\xf9\x20\x6a\xa8\x50\x19."s;
  f += "\x80\x02M\xe9\x03.";
  f += "\x80\x02}q\x00("s + pickle_string("little_endian") + "\x88u."s;
  f += checkpoint_pickle(true);
  f += "\x80\x02]q\x00"s + pickle_string("0") + "a."s;
  put<int64_t>(f, 4);
  return f + float_bytes({1, 2, 3, 4});
}

std::string zip_archive(const std::vector<std::pair<std::string, std::string>>& entries) {
  return bytes_written_by([&](const fs::path& path) {
    int err = 0;
    zip_t* z = zip_open(path.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
    if (!z) fail_file(path, "cannot create a zip seed");
    for (const auto& [name, bytes] : entries) {
      zip_source_t* s = zip_source_buffer(z, bytes.data(), bytes.size(), 0);
      zip_file_add(z, name.c_str(), s, ZIP_FL_OVERWRITE);
    }
    if (zip_close(z) != 0) fail_file(path, "cannot write a zip seed");
  });
}

const bool pickle = register_target({
    "pickle",
    [] {
      return std::vector<std::string>{
          "\x80\x02]q\x00(K\x01J\xff\xff\xff\xff\x8a\x02\x00\x01G@\x09!\xfbTD-\x18\x88N"s + pickle_string("s") +
              "C\x03" "abce.",  // list of ints, float, bool, None, str, bytes
          "\x80\x04\x95\x0c\x00\x00\x00\x00\x00\x00\x00}\x94\x8c\x01k\x94\x8c\x01v\x94s."s,  // protocol 4 frame
          // {Cls: 1, "o": Obj() with state}: a class as a key, an instance built (Lightning's callbacks)
          "\x80\x02}q\x00(cmod\nCls\nK\x01X\x01\x00\x00\x00ocmod\nObj\n)\x81}X\x01\x00\x00\x00" "aK\x02sbu."s,
          // an instance whose BUILD state is itself
          "\x80\x02" "cmod\nC\n)\x81q\x00}X\x01\x00\x00\x00" "aK\x01sbh\x00" "b."s,
      };
    },
    [](const uint8_t* data, size_t size) {
      // Both readings: the one that keeps unknown classes opaque (LaMa's Lightning checkpoint),
      // then the strict one, which may refuse what the first accepted.
      for (const bool opaque : {true, false}) {
        ByteReader reader(data, size, "input.pkl");
        PickleOptions options;
        options.opaque_objects = opaque;
        try {
          const PickleValue value = unpickle(reader, "data.pkl", {}, options);
          std::map<std::string, PthTensor> tensors;
          collect_tensors(value, "", tensors, "input.pkl");
          extras_to_json(value);
        } catch (const Error&) {
          if (opaque) throw;
        }
      }
    }});

const bool pth = register_target({
    "pth",
    [] {
      return std::vector<std::string>{
          zip_archive({{"archive/data.pkl", checkpoint_pickle(false)},
                       {"archive/byteorder", "little"},
                       {"archive/data/0", float_bytes({1, 2, 3, 4})},
                       {"archive/version", "3\n"}}),
          legacy_checkpoint()};
    },
    [](const uint8_t* data, size_t size) {
      const fs::path path = scratch_dir() / "input.pth";
      write_file(path, data, size);
      const PickleValue value = read_pth(path);
      std::map<std::string, PthTensor> tensors;
      collect_tensors(value, "", tensors, path);
      for (const auto& [name, tensor] : tensors) tensor.contiguous_bytes();
      extras_to_json(value);
    }});

// ---- COLMAP -------------------------------------------------------------------------------

ColmapModel small_colmap_model() {
  ColmapModel m;
  ColmapCamera pinhole;
  pinhole.id = 1;
  pinhole.model = "PINHOLE";
  pinhole.width = 64;
  pinhole.height = 48;
  pinhole.params = {50, 52, 32, 24};
  m.cameras[1] = pinhole;
  ColmapCamera radial = pinhole;
  radial.id = 2;
  radial.model = "OPENCV";
  radial.params = {50, 50, 32, 24, 0.01, -0.02, 0.001, 0.002};
  m.cameras[2] = radial;
  for (int id : {1, 2}) {
    ColmapImage image;
    image.id = id;
    image.camera_id = id;
    image.name = fmt::format("img{}.jpg", id);
    image.qvec = Eigen::Vector4d(1, 0, 0, 0);
    image.tvec = Eigen::Vector3d(id, 0, 1);
    image.xys = {{10.5, 20.25}, {3, 4}};
    image.point3d_ids = {1, -1};
    m.images[id] = image;
  }
  ColmapPoint point;
  point.id = 1;
  point.xyz = Eigen::Vector3d(0.5, -1, 4);
  point.rgb = {200, 100, 50};
  point.error = 0.7;
  point.track = {{1, 0}, {2, 0}};
  m.points[1] = point;
  return m;
}

// The input's first byte picks the file (cameras, images, points3D), the rest is its
// content; the other files of the model are the small valid ones.
void colmap_target(const std::string& name, const std::string& ext, bool binary) {
  static const char* stems[3] = {"cameras", "images", "points3D"};
  register_target({
      name,
      [=] {
        const fs::path dir = scratch_dir() / ("seed-" + name);
        write_colmap_model(dir, small_colmap_model(), binary);
        std::vector<std::string> seeds;
        for (int k = 0; k < 3; ++k)
          seeds.push_back(static_cast<char>(k) +
                          bytes_written_by([&](const fs::path& p) { fs::copy_file(dir / (stems[k] + ext), p); }));
        return seeds;
      },
      [=](const uint8_t* data, size_t size) {
        if (size == 0) return;
        const int which = data[0] % 3;
        const fs::path dir = scratch_dir() / (name + "-" + stems[which]);
        if (!fs::exists(dir)) write_colmap_model(dir, small_colmap_model(), binary);
        write_file(dir / (stems[which] + ext), data + 1, size - 1);
        read_colmap_model(dir);
      }});
}

const bool colmap = (colmap_target("colmap_binary", ".bin", true), colmap_target("colmap_text", ".txt", false), true);

// ---- images and masks ---------------------------------------------------------------------

std::vector<std::string> image_seeds() {
  std::vector<std::string> seeds;
  Image rgb(5, 4, 3, 0.25f), grey(3, 2, 1, 1.f), rgba(4, 4, 4, 0.5f);
  rgb.at(1, 2, 0) = 1.f;
  seeds.push_back(bytes_written_by([&](const fs::path& p) { write_png(p, rgb); }));
  seeds.push_back(bytes_written_by([&](const fs::path& p) { write_png(p, grey, 16); }));
  seeds.push_back(bytes_written_by([&](const fs::path& p) { write_png(p, rgba); }));
  seeds.push_back(bytes_written_by([&](const fs::path& p) { write_jpeg(p, rgb, 80); }));
  return seeds;
}

const bool image = register_target({
    "image", image_seeds,
    [](const uint8_t* data, size_t size) {
      const fs::path path = scratch_dir() / "input.png";
      write_file(path, data, size);
      const ImageInfo info = probe_image(path);
      // Decoding allocates what the header claims: a claim of more than 256k pixels is left to
      // the probe above, so that the fuzzer spends its time on the decoders' logic.
      if (static_cast<int64_t>(info.width) * info.height > (1 << 18)) return;
      decode_image(path);  // read_image_rgb is this plus alpha compositing
      read_mask(path);
    }});

// ---- reconstruct's checkpoint record (--resume) -------------------------------------------

const bool reconstruct_checkpoint = register_target({
    "reconstruct_checkpoint",
    [] {
      ReconstructCheckpoint c;
      c.fingerprint = "667931cc5e53bfda";
      c.step = 1000;
      c.fraction = 1.0 / 3;
      c.steps = 3000;
      ReconstructCheckpoint timed = c;
      timed.steps = 0;
      timed.time_budget_s = 540;
      return std::vector<std::string>{checkpoint_json(c), checkpoint_json(timed)};
    },
    [](const uint8_t* data, size_t size) {
      const ReconstructCheckpoint c =
          parse_checkpoint(std::string(reinterpret_cast<const char*>(data), size), "scene.checkpoint.json");
      // Taken: a run that had not ended, of steps or of time, an SH degree a splat file holds.
      if (!(c.fraction >= 0 && c.fraction < 1) || c.step < 0 || c.sh_degree < 0 || c.sh_degree > 3 ||
          (c.steps == 0 && c.time_budget_s == 0))
        std::abort();
    }});

}  // namespace
}  // namespace ii::fuzz
