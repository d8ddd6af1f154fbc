// A box around an object without a segmentation network: GrabCut in the box finds an object of two
// colours on a textured floor (and on the statue, through `masks --box`, lifted to every view);
// clicks in the box are the object and points that are not are kept out; every bad box is one
// clear message, and the command then writes nothing.
#include <gtest/gtest.h>

#include <random>

#include <nlohmann/json.hpp>

#include "data/masks.h"
#include "data/scene.h"
#include "edit/box_select.h"
#include "edit/propagate.h"
#include "io/image.h"
#include "test_support.h"

namespace ii {
namespace {
namespace box_select_test {

// A 160 x 120 photo: a floor of grey-green noise (seeded) and, on it, an object whose top half
// is red and bottom half blue (a box with a lit and a shaded side), at columns 60-109, rows 30-89.
struct Photo {
  Image rgb{160, 120, 3};
  Image object{160, 120, 1};
};

Photo two_coloured_object() {
  Photo p;
  std::mt19937 rng(41);
  std::uniform_real_distribution<float> noise(-0.08f, 0.08f);
  for (int y = 0; y < 120; ++y)
    for (int x = 0; x < 160; ++x) {
      const bool inside = x >= 60 && x < 110 && y >= 30 && y < 90;
      const float n = noise(rng);
      const float rgb[3] = {inside ? (y < 60 ? 0.85f : 0.15f) : 0.45f, inside ? 0.15f : 0.55f,
                            inside ? (y < 60 ? 0.15f : 0.8f) : 0.4f};
      for (int c = 0; c < 3; ++c) p.rgb.pixels[(static_cast<size_t>(y) * 160 + x) * 3 + c] = rgb[c] + n;
      p.object.at(y, x) = inside ? 1.f : 0.f;
    }
  return p;
}

TEST(BoxSelect, GrabCutFindsAnObjectOfTwoColoursInItsBox) {
  const Photo p = two_coloured_object();
  // The object's box grown by 5 % of its width and height.
  const Image mask = object_in_box(p.rgb, "floor", {58.75, 28.5, 111.25, 91.5});
  ASSERT_EQ(mask.width, 160);
  const MaskAgreement a = mask_agreement(mask, p.object);
  EXPECT_GT(a.recall, 0.97);
  EXPECT_GT(a.precision, 0.97);
}

TEST(BoxSelect, ClicksInTheBoxAreTheObjectAndPointsThatAreNotAreKeptOut) {
  const Photo p = two_coloured_object();
  const ViewBox box{40, 15, 130, 105};
  // Alone, GrabCut takes the object and leaves the floor.
  const Image alone = object_in_box(p.rgb, "floor", box);
  EXPECT_EQ(alone.at(45, 85), 1.f);
  EXPECT_EQ(alone.at(95, 50), 0.f);
  // A point on the object said not to be it, and a click on the floor, win over the colours there.
  const Image seeded = object_in_box(p.rgb, "floor", box, {{50.5, 95.5}}, {{85.5, 45.5}});
  EXPECT_EQ(seeded.at(45, 85), 0.f);
  EXPECT_EQ(seeded.at(95, 50), 1.f);
  EXPECT_EQ(seeded.at(75, 85), 1.f);  // the rest of the object stays
  // Nothing outside the box, whatever GrabCut decides.
  const Image wide = object_in_box(p.rgb, "floor", box, {{50.5, 95.5}});
  for (int y = 0; y < 120; ++y)
    for (int x = 0; x < 160; ++x)
      if (x < 40 || x >= 130 || y < 15 || y >= 105) ASSERT_EQ(wide.at(y, x), 0.f) << x << "," << y;
}

TEST(BoxSelect, BadBoxesAreOneClearMessageEach) {
  const Photo p = two_coloured_object();
  auto error = [&](const ViewBox& box, std::vector<Click> clicks = {}) {
    return test::error_message([&] { object_in_box(p.rgb, "IMG_1", box, clicks); });
  };
  EXPECT_EQ(error({100, 50, 170, 90}), "view IMG_1: the box 100,50,170,90 reaches outside its photo (160x120)");
  EXPECT_EQ(error({-5, 50, 70, 90}), "view IMG_1: the box -5,50,70,90 reaches outside its photo (160x120)");
  EXPECT_EQ(error({60, 50, 61.5, 90}),
            "view IMG_1: the box 60,50,61.5,90 is under 2 pixels wide or high: draw it around the object");
  EXPECT_EQ(error({0, 0, 160, 120}),
            "view IMG_1: the box 0,0,160,120 covers the whole photo (160x120): without a segmentation network the "
            "photo outside the box is what the object is told apart from; draw the box around the object");
  EXPECT_EQ(error({58, 28, 112, 92}, {{20, 20}}),
            "view IMG_1: the click (20, 20) is outside the box 58,28,112,92: clicks with a box are on the object "
            "inside it");
  // A photo of one colour holds nothing GrabCut can tell from the rest.
  EXPECT_EQ(test::error_message([] { object_in_box(Image(160, 120, 3, 0.5f), "IMG_1", {40, 30, 120, 90}); }),
            "view IMG_1: GrabCut found no object in the box 40,30,120,90");
  // A box of zero width does not get that far: the parser refuses it.
  EXPECT_EQ(test::error_message([] { parse_view_box("60,50,60,90", "--box"); }),
            "--box 60,50,60,90: expected X0,Y0,X1,Y1 with X1 > X0 and Y1 > Y0");
  // With a segmenter the whole photo is a box like another (the network tells the object apart).
  EXPECT_NO_THROW(check_box("IMG_1", 160, 120, {0, 0, 160, 120}, {}, true));
}

// `masks --box` on the statue without a segmenter: the boxed view's mask is GrabCut's, every view
// gets its lifted mask, and the report says so.
TEST(BoxSelect, TheMasksCommandSelectsInTheBoxAndLiftsItToEveryView) {
  const std::string missing = test::shared_missing("data/statue");
  if (!missing.empty()) GTEST_SKIP() << missing;
  const std::filesystem::path dir = test::temp_dir("box-select-masks");
  const std::string cli = test::cli_executable().string();
  // IMG_2707's label's box grown by 5 %.
  ASSERT_EQ(test::run_command("env -u INSTAINPAINT_SEGMENTER " + cli + " masks --scene " +
                                  test::shared_path("data/statue").string() +
                                  " --view IMG_2707 --box 217.4,122.7,369.6,346.3 --height 128 --device cpu --out " +
                                  (dir / "masks").string(),
                              dir / "log.txt"),
            0)
      << test::file_bytes(dir / "log.txt");
  EXPECT_NE(test::file_bytes(dir / "log.txt").find("boxed view's mask: GrabCut in the box (no --segmenter)"),
            std::string::npos)
      << test::file_bytes(dir / "log.txt");
  const nlohmann::json report = nlohmann::json::parse(test::file_bytes(dir / "masks" / "masks.json"));
  EXPECT_EQ(report["clicked_mask"], "GrabCut in the box");
  EXPECT_EQ(report["box"], nlohmann::json({217.4, 122.7, 369.6, 346.3}));
  EXPECT_GT(report["carved"].get<int>(), 0);
  // Its own view is compared too (a box's mask is made, not drawn), and holds the statue.
  const nlohmann::json& own = report["views"][0];
  ASSERT_EQ(own["name"], "IMG_2707");
  EXPECT_GT(own["recall"].get<double>(), 0.9);
  EXPECT_GT(own["precision"].get<double>(), 0.95);
  EXPECT_GT(report["agreement"]["mean_recall"].get<double>(), 0.8);
}

TEST(BoxSelect, ABadBoxOnTheCommandLineWritesNothing) {
  const std::string missing = test::shared_missing("data/statue");
  if (!missing.empty()) GTEST_SKIP() << missing;
  const std::filesystem::path dir = test::temp_dir("box-select-bad");
  const std::string cli = test::cli_executable().string();
  const std::string masks = "env -u INSTAINPAINT_SEGMENTER " + cli + " masks --scene " +
                            test::shared_path("data/statue").string() + " --view IMG_2707 --height 128 --out " +
                            (dir / "out").string();
  const std::vector<std::pair<std::string, std::string>> cases = {
      {" --box 400,100,600,300", "view IMG_2707: the box 400,100,600,300 reaches outside its photo (504x378)"},
      {" --box 200,100,200,300", "--box 200,100,200,300: expected X0,Y0,X1,Y1 with X1 > X0 and Y1 > Y0"},
      {" --box 0,0,504,378", "view IMG_2707: the box 0,0,504,378 covers the whole photo (504x378)"},
      {" --box 217,122,369,346 --click 20,20",
       "view IMG_2707: the click (20, 20) is outside the box 217,122,369,346"},
      {" --box 217,122,369,346 --mode insert", "--box selects an object to remove: --mode insert needs --mask"},
  };
  for (const auto& [options, message] : cases) {
    EXPECT_NE(test::run_command(masks + options, dir / "log.txt"), 0) << options;
    EXPECT_NE(test::file_bytes(dir / "log.txt").find(message), std::string::npos)
        << options << ": " << test::file_bytes(dir / "log.txt");
    EXPECT_FALSE(std::filesystem::exists(dir / "out")) << options;
  }
}

}  // namespace box_select_test
}  // namespace
}  // namespace ii
