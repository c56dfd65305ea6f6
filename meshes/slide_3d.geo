// Sliding off an edge (finite sliding), 3D: a plate [0, L] x [0, W] x [-H, 0] and a cube of edge a at
// [x0, x0 + a] x [y0, y0 + a] x [gap, gap + a], separate volumes with separate nodes
// (non-matching interface: plate cells of size h, cube cells of size hu).
// kind: 0 = hexahedra, 1 = tetrahedra (each structured cell cut into 6 tetrahedra).
//   Physical volumes:  "upper" (the cube), "lower" (the plate).
//   Physical surfaces: "upper_contact" (the cube's bottom), "lower_contact" (the plate's
//                      top), "lower_bottom", "upper_rest", "lower_sides".
SetFactory("OpenCASCADE");
DefineConstant[
  L = {2, Name "L"}, W = {1, Name "W"}, H = {0.25, Name "H"},
  x0 = {0.1, Name "x0"}, y0 = {0.25, Name "y0"}, a = {0.5, Name "a"},
  gap = {0.001, Name "gap"}, h = {0.125, Name "h"}, hu = {0.1, Name "hu"},
  kind = {0, Choices {0 = "hexahedra", 1 = "tetrahedra"}, Name "kind"}
];
Mesh.ElementOrder = 1;

Box(1) = {0, 0, -H, L, W, H};        // lower
Box(2) = {x0, y0, gap, a, a, a};     // upper

e = 1e-6;
bl() = Abs(Boundary{ Volume{1}; });
bu() = Abs(Boundary{ Volume{2}; });
box() = Surface In BoundingBox{-e, -e, -e, L + e, W + e, e};
rest() = bl(); rest() -= box(); lower_contact() = bl(); lower_contact() -= rest();
box() = Surface In BoundingBox{-e, -e, -H - e, L + e, W + e, -H + e};
rest() = bl(); rest() -= box(); lower_bottom() = bl(); lower_bottom() -= rest();
lower_sides() = bl();
lower_sides() -= {lower_contact(), lower_bottom()};
box() = Surface In BoundingBox{x0 - e, y0 - e, gap - e, x0 + a + e, y0 + a + e, gap + e};
rest() = bu(); rest() -= box(); upper_contact() = bu(); upper_contact() -= rest();
upper_rest() = bu();
upper_rest() -= {upper_contact()};

// Structured cells: each edge by its own length over h (plate) or hu (cube).
cl() = Abs(Boundary{ Surface{bl()}; });
cu() = Abs(Boundary{ Surface{bu()}; });
For i In {0 : #cl() - 1}
  bb() = BoundingBox Curve{cl(i)};
  len = Max(Abs(bb(3) - bb(0)), Max(Abs(bb(4) - bb(1)), Abs(bb(5) - bb(2))));
  Transfinite Curve{cl(i)} = Round(len / h) + 1;
EndFor
For i In {0 : #cu() - 1}
  bb() = BoundingBox Curve{cu(i)};
  len = Max(Abs(bb(3) - bb(0)), Max(Abs(bb(4) - bb(1)), Abs(bb(5) - bb(2))));
  Transfinite Curve{cu(i)} = Round(len / hu) + 1;
EndFor
Transfinite Surface{bl(), bu()};
Transfinite Volume{1, 2};
If (kind == 0)
  Recombine Surface{bl(), bu()};
EndIf

Physical Volume("upper") = {2};
Physical Volume("lower") = {1};
Physical Surface("upper_contact") = {upper_contact()};
Physical Surface("lower_contact") = {lower_contact()};
Physical Surface("lower_bottom") = {lower_bottom()};
Physical Surface("upper_rest") = {upper_rest()};
Physical Surface("lower_sides") = {lower_sides()};
