#pragma once
// A small synthetic room (synth's procedural object, one object-free test view) written in the
// SPIn-NeRF layout with depth maps, for tests that need a scene with exact geometry.
#include <filesystem>

#include "synth/synth_scene.h"
#include "synth/synth_writer.h"
#include "test_support.h"

namespace ii::test {

// `views` input views of side x side pixels, from `seed`; returns the scene folder.
inline std::filesystem::path synthetic_room(const std::string& tag, int views, int side, uint64_t seed) {
  const std::filesystem::path dir = temp_dir(tag) / "scene";
  synth::SynthOptions so;
  so.views = views;
  so.test_views = 1;
  so.width = so.height = side;
  so.object = synth::ObjectSource::procedural;
  synth::write_synth_scene(synth::generate_scene(so, seed), dir, synth::SynthWriteOptions());
  return dir;
}

}  // namespace ii::test
