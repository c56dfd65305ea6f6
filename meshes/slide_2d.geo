// Sliding off an edge (finite sliding), 2D: a long lower block [0, L] x [-H, 0] and a short upper
// block [x0, x0 + a] x [gap, gap + b], separate surfaces with separate nodes (non-matching
// interface: lower cells of size h, upper cells of size hu).
// kind: 0 = quadrilaterals, 1 = triangles.
//   Physical surfaces: "upper", "lower".
//   Physical curves:   "upper_contact" (upper block's bottom), "lower_contact" (lower block's
//                      top), "lower_bottom", "upper_rest", "lower_sides".
SetFactory("OpenCASCADE");
DefineConstant[
  L = {4, Name "L"}, H = {0.5, Name "H"}, x0 = {0.2, Name "x0"}, a = {1, Name "a"},
  b = {0.5, Name "b"}, gap = {0.001, Name "gap"}, h = {0.1, Name "h"}, hu = {0.125, Name "hu"},
  kind = {0, Choices {0 = "quadrilaterals", 1 = "triangles"}, Name "kind"}
];
Mesh.ElementOrder = 1;

Rectangle(1) = {0, -H, 0, L, H};      // lower
Rectangle(2) = {x0, gap, 0, a, b};    // upper

e = 1e-6;
bl() = Abs(Boundary{ Surface{1}; });
bu() = Abs(Boundary{ Surface{2}; });
box() = Curve In BoundingBox{-e, -e, -e, L + e, e, e};
rest() = bl(); rest() -= box(); lower_contact() = bl(); lower_contact() -= rest();
box() = Curve In BoundingBox{-e, -H - e, -e, L + e, -H + e, e};
rest() = bl(); rest() -= box(); lower_bottom() = bl(); lower_bottom() -= rest();
lower_sides() = bl();
lower_sides() -= {lower_contact(), lower_bottom()};
box() = Curve In BoundingBox{x0 - e, gap - e, -e, x0 + a + e, gap + e, e};
rest() = bu(); rest() -= box(); upper_contact() = bu(); upper_contact() -= rest();
upper_rest() = bu();
upper_rest() -= {upper_contact()};

// Structured cells: the long sides by h (lower) and hu (upper), the short ones likewise.
Transfinite Curve{lower_contact(), lower_bottom()} = Round(L / h) + 1;
Transfinite Curve{lower_sides()} = Round(H / h) + 1;
For i In {0 : #bu() - 1}
  // upper: horizontal edges a / hu cells, vertical b / hu
  bb() = BoundingBox Curve{bu(i)};
  If (Abs(bb(4) - bb(1)) > Abs(bb(3) - bb(0)))
    Transfinite Curve{bu(i)} = Round(b / hu) + 1;
  Else
    Transfinite Curve{bu(i)} = Round(a / hu) + 1;
  EndIf
EndFor
Transfinite Surface{1, 2};
If (kind == 0)
  Recombine Surface{1, 2};
EndIf

Physical Surface("upper") = {2};
Physical Surface("lower") = {1};
Physical Curve("upper_contact") = {upper_contact()};
Physical Curve("lower_contact") = {lower_contact()};
Physical Curve("lower_bottom") = {lower_bottom()};
Physical Curve("upper_rest") = {upper_rest()};
Physical Curve("lower_sides") = {lower_sides()};
