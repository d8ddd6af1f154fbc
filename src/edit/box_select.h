#pragma once
// A box drawn around an object selects it without a segmentation network: OpenCV's GrabCut in the
// box on that view's photo, the photo outside the box the background for certain, the box's inside
// probably the object (clicks in it are the object for certain, points that are not the object the
// background). The classical answer for a compact object of several colours, where a click's
// growth by colour stops at its shaded side. The mask is then lifted to every view and carved like
// a drawn one (edit/scene_masks.h). Torch-free.
//
//   const Image mask = object_in_box(photo, "IMG_2707", parse_view_box("210,120,390,330", "--box"));
#include <string>
#include <vector>

#include "camera/click.h"
#include "io/image.h"

namespace ii {

// Measured on the statue's 8 views spread over its 29 (each view's label's box grown 5 %; the view's
// own mask against its label, 2026-12-07): a margin of 0.1 0.940 / 0.991 recall / precision (worst
// view 0.908 / 0.978); 0.2 and 0.5, 0.947 / 0.896 and 0.942 / 0.905 (a bush behind the statue
// taken: a wider margin's background holds less of what stands right around the object); 5
// iterations 0.928 / 0.993. 320 pixels and the photo's full size (504 x 378) alike.
struct BoxSelectOptions {
  int iterations = 3;  // GrabCut's
  // GrabCut works on the box and this fraction of its larger side around it (the background's
  // colours nearest the object), at most `grabcut_size` pixels on the crop's larger side (0: at
  // the photo's size); the answer is brought back to the photo's size.
  double margin = 0.1;
  int grabcut_size = 320;
  // Clicks and points that are not the object seed discs of this fraction of the box's larger side.
  double seed_radius = 0.02;
};

// The checks a box gets before any work, each an Error naming the view: inside the photo
// (`width` x `height`), not all of it (GrabCut needs background: with_network false), and every
// click inside it.
void check_box(const std::string& view, int width, int height, const ViewBox& box, const std::vector<Click>& clicks,
               bool with_network);

// The object in `box` on `photo` (view `view`, for errors): values 0/1 at the photo's size.
// `clicks` are on the object, `not_clicks` are not. An Error when GrabCut finds nothing in the box.
Image object_in_box(const Image& photo, const std::string& view, const ViewBox& box,
                    const std::vector<Click>& clicks = {}, const std::vector<Click>& not_clicks = {},
                    const BoxSelectOptions& options = {});

}  // namespace ii
