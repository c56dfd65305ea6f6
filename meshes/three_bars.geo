// Three strips in a row along x for contact between several pairs of bodies (a chain):
// "left" = [0, L] x [0, H], "middle" = [L + gap, 3 L + gap] x [0, H] (twice as long) and
// "right" = [3 L + 2 gap, 4 L + 2 gap] x [0, H], structured quadrilaterals, n elements per
// length L along x and ny across. The bodies are separate surfaces with no shared node.
//   Physical surfaces: "left", "middle", "right".
//   Physical curves:   "left_contact" (x = L), "middle_left" (x = L + gap),
//                      "middle_right" (x = 3 L + gap), "right_contact" (x = 3 L + 2 gap): the
//                      facing ends; "free": the other edges of the three strips.
// Override with e.g. `-setnumber n 40 -setnumber ny 1 -setnumber gap 0.02`.
SetFactory("OpenCASCADE");
DefineConstant[
  L = {1.0, Name "L"},
  H = {0.1, Name "H"},
  gap = {0.01, Name "gap"},
  n = {20, Name "n"},
  ny = {2, Name "ny"}
];
Mesh.ElementOrder = 1;

Rectangle(1) = {0, 0, 0, L, H};
Rectangle(2) = {L + gap, 0, 0, 2 * L, H};
Rectangle(3) = {3 * L + 2 * gap, 0, 0, L, H};

e = 1e-6 * L;
all() = Abs(Boundary{ Surface{1, 2, 3}; });
left_contact() = Curve In BoundingBox{L - e, -e, -e, L + e, H + e, e};
middle_left() = Curve In BoundingBox{L + gap - e, -e, -e, L + gap + e, H + e, e};
middle_right() = Curve In BoundingBox{3 * L + gap - e, -e, -e, 3 * L + gap + e, H + e, e};
right_contact() = Curve In BoundingBox{3 * L + 2 * gap - e, -e, -e, 3 * L + 2 * gap + e, H + e, e};
ends() = Curve In BoundingBox{-e, -e, -e, e, H + e, e};
ends() += Curve In BoundingBox{4 * L + 2 * gap - e, -e, -e, 4 * L + 2 * gap + e, H + e, e};
free() = all();
free() -= left_contact();
free() -= middle_left();
free() -= middle_right();
free() -= right_contact();
short() = Curve In BoundingBox{-e, -e, -e, L + e, e, e};
short() += Curve In BoundingBox{-e, H - e, -e, L + e, H + e, e};
short() += Curve In BoundingBox{3 * L + 2 * gap - e, -e, -e, 4 * L + 2 * gap + e, e, e};
short() += Curve In BoundingBox{3 * L + 2 * gap - e, H - e, -e, 4 * L + 2 * gap + e, H + e, e};
long() = Curve In BoundingBox{L + gap - e, -e, -e, 3 * L + gap + e, e, e};
long() += Curve In BoundingBox{L + gap - e, H - e, -e, 3 * L + gap + e, H + e, e};

Transfinite Curve{short()} = n + 1;
Transfinite Curve{long()} = 2 * n + 1;
Transfinite Curve{left_contact(), middle_left(), middle_right(), right_contact(), ends()} = ny + 1;
Transfinite Surface{1, 2, 3};
Recombine Surface{1, 2, 3};

Physical Surface("left") = {1};
Physical Surface("middle") = {2};
Physical Surface("right") = {3};
Physical Curve("left_contact") = {left_contact()};
Physical Curve("middle_left") = {middle_left()};
Physical Curve("middle_right") = {middle_right()};
Physical Curve("right_contact") = {right_contact()};
Physical Curve("free") = {free()};
