// Two identical strips side by side along x for body-to-body contact (e.g. a bar impact):
// "left" = [0, L] x [0, H] and "right" = [L + gap, 2 L + gap] x [0, H], structured
// quadrilaterals, n elements along the length and ny across. The bodies are separate
// surfaces with no shared node.
//   Physical surfaces: "left", "right".
//   Physical curves:   "left_contact" (x = L), "right_contact" (x = L + gap): the facing ends;
//                      "left_free", "right_free": the three other edges of each strip;
//                      "left_end" (x = 0), "right_end" (x = 2 L + gap): the far ends, also in
//                      <body>_free, for a test that holds or pushes them.
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
Rectangle(2) = {L + gap, 0, 0, L, H};

// Edges by bounding box, each intersected with its own strip's boundary.
e = 1e-6 * L;
bl() = Abs(Boundary{ Surface{1}; });
br() = Abs(Boundary{ Surface{2}; });
left_contact() = Curve In BoundingBox{L - e, -e, -e, L + e, H + e, e};
left_end() = Curve In BoundingBox{-e, -e, -e, e, H + e, e};
right_contact() = Curve In BoundingBox{L + gap - e, -e, -e, L + gap + e, H + e, e};
right_end() = Curve In BoundingBox{2 * L + gap - e, -e, -e, 2 * L + gap + e, H + e, e};
left_free() = bl();
left_free() -= left_contact();
right_free() = br();
right_free() -= right_contact();
long() = Curve In BoundingBox{-e, -e, -e, 2 * L + gap + e, e, e};
long() += Curve In BoundingBox{-e, H - e, -e, 2 * L + gap + e, H + e, e};

Transfinite Curve{long()} = n + 1;
Transfinite Curve{left_contact(), left_end(), right_contact(), right_end()} = ny + 1;
Transfinite Surface{1, 2};
Recombine Surface{1, 2};

Physical Surface("left") = {1};
Physical Surface("right") = {2};
Physical Curve("left_contact") = {left_contact()};
Physical Curve("right_contact") = {right_contact()};
Physical Curve("left_free") = {left_free()};
Physical Curve("right_free") = {right_free()};
Physical Curve("left_end") = {left_end()};
Physical Curve("right_end") = {right_end()};
