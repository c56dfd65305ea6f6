// Mortar patch test in 3D, non-matching interface: a lower unit cube [0,1]^2 x [-1,0] with
// n_lower cells per direction and an upper unit cube [0,1]^2 x [gap, 1 + gap] with n_upper
// cells per direction, structured. The cubes are separate volumes with separate nodes even
// for gap = 0 (two coincident interface faces, each with its own nodes: no BooleanFragments or
// Coherence is applied, and the OpenCASCADE kernel does not merge them).
// kind: 0 = hexahedra, 1 = tetrahedra (each structured cell cut into 6 tetrahedra: the
// transfinite algorithm on triangulated faces), 2 = mixed (lower hexahedra, upper tetrahedra).
//   Physical volumes:  "upper", "lower".
//   Physical surfaces: "upper_contact" (upper cube's bottom z = gap), "lower_contact" (lower
//                      cube's top z = 0), "upper_top", "lower_bottom", "upper_sides",
//                      "lower_sides" (the four vertical faces of each cube).
// Override with e.g. `-setnumber kind 2 -setnumber n_upper 5 -setnumber gap 0.01`.
SetFactory("OpenCASCADE");
DefineConstant[
  gap = {0, Name "gap"},
  n_lower = {3, Name "n_lower"},
  n_upper = {4, Name "n_upper"},
  kind = {0, Choices {0 = "hexahedra", 1 = "tetrahedra", 2 = "lower hexahedra, upper tetrahedra"},
          Name "kind"}
];
Mesh.ElementOrder = 1;

Box(1) = {0, 0, -1, 1, 1, 1};     // lower
Box(2) = {0, 0, gap, 1, 1, 1};    // upper

// Faces by bounding box, intersected with each cube's own boundary (for gap = 0 the
// interface box holds both cubes' faces): pick = own - (own - box).
e = 1e-6;
bl() = Abs(Boundary{ Volume{1}; });
bu() = Abs(Boundary{ Volume{2}; });
box() = Surface In BoundingBox{-e, -e, -e, 1 + e, 1 + e, e};
rest() = bl(); rest() -= box(); lower_contact() = bl(); lower_contact() -= rest();
box() = Surface In BoundingBox{-e, -e, -1 - e, 1 + e, 1 + e, -1 + e};
rest() = bl(); rest() -= box(); lower_bottom() = bl(); lower_bottom() -= rest();
lower_sides() = bl();
lower_sides() -= {lower_contact(), lower_bottom()};
box() = Surface In BoundingBox{-e, -e, gap - e, 1 + e, 1 + e, gap + e};
rest() = bu(); rest() -= box(); upper_contact() = bu(); upper_contact() -= rest();
box() = Surface In BoundingBox{-e, -e, 1 + gap - e, 1 + e, 1 + e, 1 + gap + e};
rest() = bu(); rest() -= box(); upper_top() = bu(); upper_top() -= rest();
upper_sides() = bu();
upper_sides() -= {upper_contact(), upper_top()};

cl() = Abs(Boundary{ Surface{bl()}; });
cu() = Abs(Boundary{ Surface{bu()}; });
Transfinite Curve{cl()} = n_lower + 1;
Transfinite Curve{cu()} = n_upper + 1;
Transfinite Surface{bl(), bu()};
Transfinite Volume{1, 2};
If (kind == 0)
  Recombine Surface{bl(), bu()};
ElseIf (kind == 2)
  Recombine Surface{bl()};
EndIf

Physical Volume("upper") = {2};
Physical Volume("lower") = {1};
Physical Surface("upper_contact") = {upper_contact()};
Physical Surface("lower_contact") = {lower_contact()};
Physical Surface("upper_top") = {upper_top()};
Physical Surface("lower_bottom") = {lower_bottom()};
Physical Surface("upper_sides") = {upper_sides()};
Physical Surface("lower_sides") = {lower_sides()};
