#pragma once
// Amodal completion of an object's box from what its class is known to measure. A depth camera
// ranges only the faces that look at it: a chair seen from behind is its backrest (0.2 m deep),
// a car seen from its tail is as deep as the tail's few centimetres of curvature, and no fusion
// of such views can measure the far side. Where every view lies on one side of the box along
// an axis, the far face along it was never seen; a box thinner there than its class's typical
// size is grown away from the viewers to that size (object-SLAM size priors, as in CubeSLAM),
// or past the image border where its views were cut (ObjectDatabase: a third of them). A measured
// side is never shrunk and a fully seen object is never changed.
#include <optional>
#include <string>
#include <vector>

#include "core/eigen_types.hpp"
#include "semantic/object_geometry.hpp"

namespace kestrel::semantic {

struct FootprintPrior {
  double length = 0.0;  // metres, the class's typical longer side
  double width = 0.0;   // ... and shorter side
};

// The footprint prior of a COCO class; nothing for classes whose size varies too much to bound
// (tv, potted plant, cup) or that are never static objects here (person).
std::optional<FootprintPrior> footprint_prior(const std::string& label);

// `viewpoints`: the world positions of the cameras that measured the box. Returns the box with
// each one-sided axis grown to the prior (see above). When both axes are one-sided (seen from a
// corner only), the prior's length goes to the axis already measured longer. When only one is,
// it takes the prior's width if the other side measures nearer the prior's length than its
// width, else the length (a car seen end-on is as wide as a car and must be a car's length deep).
// `cut_towards`: where the object went on past the image's left or right border in the views
// that measured it (world, horizontal; zero: never cut). An axis to be grown grows that way
// when the cut lies along it: the hidden part is beyond the border, and the end away from the
// viewers was then seen (a sofa at the edge of every view).
UprightBox complete_with_prior(const UprightBox& box, const std::vector<Vec3>& viewpoints,
                               const FootprintPrior& prior, const Vec2& cut_towards = Vec2::Zero());

}  // namespace kestrel::semantic
