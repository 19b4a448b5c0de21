#pragma once
// Where an image lands inside the square network input, and the way back for boxes.
// kLetterbox follows Darknet's letterbox_image(): keep the aspect ratio, integer sizes, centre
// with integer padding, pad value 0.5 (of 1.0). kStretch is Darknet's plain resize_image(), the
// transform YOLO-Fastest was trained with (its cfg has no letter_box=1).
namespace kestrel::detect {

enum class InputResize { kStretch, kLetterbox };

struct Letterbox {
  int image_width = 0, image_height = 0;
  int net_width = 0, net_height = 0;
  int resized_width = 0, resized_height = 0;  // the image's size inside the network input
  int pad_x = 0, pad_y = 0;                   // its top-left corner there

  static Letterbox make(int image_width, int image_height, int net_width, int net_height,
                        InputResize mode);

  double to_net_x(double image_x) const { return pad_x + image_x * resized_width / image_width; }
  double to_net_y(double image_y) const { return pad_y + image_y * resized_height / image_height; }
  double to_image_x(double net_x) const { return (net_x - pad_x) * image_width / resized_width; }
  double to_image_y(double net_y) const { return (net_y - pad_y) * image_height / resized_height; }
};

}  // namespace kestrel::detect
