// Mortar patch test in 2D, non-matching interface: a lower block [0,1] x [-1,0] with
// n_lower x n_lower structured cells and an upper block [0,1] x [gap, 1 + gap] with
// n_upper x n_upper structured cells. The blocks are separate surfaces with separate nodes
// even for gap = 0 (two coincident interface lines, each with its own nodes: no
// BooleanFragments/Coherence is applied, and the OpenCASCADE kernel does not merge them).
// kind: 0 = quadrilaterals, 1 = triangles, 2 = mixed (lower quadrilaterals, upper triangles).
//   Physical surfaces: "upper", "lower".
//   Physical curves:   "upper_contact" (upper block's bottom), "lower_contact" (lower block's
//                      top), "upper_top", "lower_bottom", "upper_sides", "lower_sides".
// Override with e.g. `-setnumber kind 2 -setnumber n_upper 7 -setnumber gap 0.01`.
SetFactory("OpenCASCADE");
DefineConstant[
  gap = {0, Name "gap"},
  n_lower = {4, Name "n_lower"},
  n_upper = {5, Name "n_upper"},
  kind = {0, Choices {0 = "quadrilaterals", 1 = "triangles", 2 = "lower quads, upper triangles"},
          Name "kind"}
];
Mesh.ElementOrder = 1;

Rectangle(1) = {0, -1, 0, 1, 1};     // lower
Rectangle(2) = {0, gap, 0, 1, 1};    // upper

// Edges by bounding box, intersected with each block's own boundary (for gap = 0 the
// interface box holds both blocks' edges).
e = 1e-6;
bl() = Abs(Boundary{ Surface{1}; });
bu() = Abs(Boundary{ Surface{2}; });
// pick = own ^ box, computed as own - (own - box)
box() = Curve In BoundingBox{-e, -e, -e, 1 + e, e, e};
rest() = bl(); rest() -= box(); lower_contact() = bl(); lower_contact() -= rest();
box() = Curve In BoundingBox{-e, -1 - e, -e, 1 + e, -1 + e, e};
rest() = bl(); rest() -= box(); lower_bottom() = bl(); lower_bottom() -= rest();
lower_sides() = bl();
lower_sides() -= {lower_contact(), lower_bottom()};
box() = Curve In BoundingBox{-e, gap - e, -e, 1 + e, gap + e, e};
rest() = bu(); rest() -= box(); upper_contact() = bu(); upper_contact() -= rest();
box() = Curve In BoundingBox{-e, 1 + gap - e, -e, 1 + e, 1 + gap + e, e};
rest() = bu(); rest() -= box(); upper_top() = bu(); upper_top() -= rest();
upper_sides() = bu();
upper_sides() -= {upper_contact(), upper_top()};

Transfinite Curve{bl()} = n_lower + 1;
Transfinite Curve{bu()} = n_upper + 1;
Transfinite Surface{1, 2};
If (kind == 0)
  Recombine Surface{1, 2};
ElseIf (kind == 2)
  Recombine Surface{1};
EndIf

Physical Surface("upper") = {2};
Physical Surface("lower") = {1};
Physical Curve("upper_contact") = {upper_contact()};
Physical Curve("lower_contact") = {lower_contact()};
Physical Curve("upper_top") = {upper_top()};
Physical Curve("lower_bottom") = {lower_bottom()};
Physical Curve("upper_sides") = {upper_sides()};
Physical Curve("lower_sides") = {lower_sides()};
