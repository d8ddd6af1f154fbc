#include <gtest/gtest.h>

#include <fstream>

#include "io/image.h"
#include "test_support.h"

namespace ii {
namespace {

namespace fs = std::filesystem;

Image gradient(int w, int h, int c, int levels) {
  Image img(w, h, c);
  for (size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = static_cast<float>(i % levels) / (levels - 1);
  return img;
}

TEST(ImageIo, Png8RoundTripIsExact) {
  const fs::path p = test::temp_dir("img") / "a.png";
  const Image img = gradient(7, 5, 3, 256);
  write_png(p, img);
  const Image back = read_image_rgb(p);
  ASSERT_EQ(back.width, 7);
  ASSERT_EQ(back.height, 5);
  for (size_t i = 0; i < img.pixels.size(); ++i) EXPECT_FLOAT_EQ(back.pixels[i], img.pixels[i]);
  const ImageInfo info = probe_image(p);
  EXPECT_EQ(info.bit_depth, 8);
  EXPECT_EQ(info.channels, 3);
}

TEST(ImageIo, Png16RoundTripIsExact) {
  const fs::path p = test::temp_dir("img") / "b.png";
  const Image img = gradient(9, 4, 3, 65536);
  write_png(p, img, 16);
  EXPECT_EQ(probe_image(p).bit_depth, 16);
  const Image back = read_image_rgb(p);
  for (size_t i = 0; i < img.pixels.size(); ++i) EXPECT_FLOAT_EQ(back.pixels[i], img.pixels[i]);
}

TEST(ImageIo, AlphaIsCompositedOnWhite) {
  const fs::path p = test::temp_dir("img") / "rgba.png";
  Image img(2, 1, 4);
  img.pixels = {0.f, 0.f, 0.f, 0.f, /* transparent black */ 1.f, 0.f, 0.f, 1.f /* opaque red */};
  write_png(p, img);
  const Image rgb = read_image_rgb(p);
  EXPECT_FLOAT_EQ(rgb.at(0, 0, 0), 1.f);
  EXPECT_FLOAT_EQ(rgb.at(0, 0, 1), 1.f);
  EXPECT_FLOAT_EQ(rgb.at(0, 1, 0), 1.f);
  EXPECT_FLOAT_EQ(rgb.at(0, 1, 1), 0.f);
  const DecodedImage d = decode_image(p);
  ASSERT_TRUE(d.alpha.has_value());
  EXPECT_FLOAT_EQ(d.alpha->pixels[0], 0.f);
}

TEST(ImageIo, MasksAcceptZeroOneAndZero255) {
  const fs::path dir = test::temp_dir("mask");
  Image m(3, 1, 1);
  m.pixels = {0.f, 1.f / 255.f, 0.f};  // a {0,1}-valued 8-bit file
  write_png(dir / "01.png", m);
  EXPECT_EQ(read_mask(dir / "01.png").pixels, (std::vector<float>{0, 1, 0}));
  m.pixels = {1.f, 0.f, 1.f};  // {0,255}
  write_png(dir / "0255.png", m);
  EXPECT_EQ(read_mask(dir / "0255.png").pixels, (std::vector<float>{1, 0, 1}));
  m.pixels = {0.f, 0.f, 0.f};
  write_png(dir / "empty.png", m);
  EXPECT_EQ(read_mask(dir / "empty.png").pixels, (std::vector<float>{0, 0, 0}));
}

TEST(ImageIo, JpegRoundTripIsClose) {
  const fs::path p = test::temp_dir("img") / "c.jpg";
  Image img(16, 16, 3, 0.5f);
  write_jpeg(p, img, 95);
  const Image back = read_image_rgb(p);
  for (float v : back.pixels) EXPECT_NEAR(v, 0.5f, 2.f / 255.f);
}

TEST(ImageIo, RealSceneImagesDecode) {
  II_REQUIRE_SHARED(p, "data/fox/images/0001.jpg");
  const ImageInfo info = probe_image(p);
  EXPECT_EQ(info.width, 540);
  EXPECT_EQ(info.height, 960);
  const Image img = read_image_rgb(p);
  EXPECT_EQ(img.pixels.size(), 540u * 960u * 3u);
}

TEST(ImageIo, BadInputIsAClearError) {
  const fs::path dir = test::temp_dir("bad");
  EXPECT_EQ(test::error_message([&] { read_image_rgb(dir / "missing.png"); }),
            (dir / "missing.png").string() + ": file not found");
  std::ofstream(dir / "empty.png").close();
  EXPECT_EQ(test::error_message([&] { read_image_rgb(dir / "empty.png"); }),
            (dir / "empty.png").string() + ": empty file, expected an image");
  std::ofstream(dir / "text.png") << "this is not an image at all";
  EXPECT_EQ(test::error_message([&] { read_image_rgb(dir / "text.png"); }),
            (dir / "text.png").string() + ": not a readable image (unknown image type)");
  // A PNG cut in the middle of its pixel data.
  const fs::path good = dir / "good.png";
  write_png(good, gradient(64, 64, 3, 251));
  std::ifstream in(good, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream(dir / "cut.png", std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  const std::string cut = test::error_message([&] { read_image_rgb(dir / "cut.png"); });
  EXPECT_EQ(cut.rfind((dir / "cut.png").string() + ": cannot decode image (", 0), 0u) << cut;
  // A decompression bomb is refused from its header, before any pixel is decoded.
  test::write_bytes(dir / "bomb.png", test::png_header(16000, 16000));
  EXPECT_EQ(test::error_message([&] { read_image_rgb(dir / "bomb.png"); }),
            (dir / "bomb.png").string() + ": 16000x16000 pixels, more than instainpaint decodes (at most 134 million)");
  EXPECT_EQ(test::error_message([&] { read_mask(dir / "bomb.png"); }),
            (dir / "bomb.png").string() + ": 16000x16000 pixels, more than instainpaint decodes (at most 134 million)");
  EXPECT_EQ(test::error_message([&] { write_png(dir / "x.png", Image{}); }),
            (dir / "x.png").string() + ": cannot write an empty image");
  EXPECT_FALSE(fs::exists(dir / "x.png"));
}

}  // namespace
}  // namespace ii
