// Two balls for 3D body-to-body contact, one above the other along z: "upper" of radius R1
// centred at (0, 0, gap/2 + R1) and "lower" of radius R2 centred at (0, 0, -gap/2 - R2), so
// their closest points (0, 0, +-gap/2) are `gap` apart. Tetrahedra of size hc_upper /
// hc_lower within rc of each contact point, growing to h at rc + 2 R / 3 (as in
// sphere_tet.geo). Each ball is cut at distance `cap` from its contact point into a cap and
// the rest (two volumes of one body, conforming across the cut); the balls are separate
// volumes with no shared node.
//   Physical volumes:  "upper", "lower".
//   Physical surfaces: "upper_contact" (upper ball's lower cap, z < gap/2 + cap),
//                      "lower_contact" (lower ball's upper cap, z > -gap/2 - cap),
//                      "upper_free", "lower_free" (the rest of each sphere).
// Override with e.g. `-setnumber hc 0.08 -setnumber h 0.4`, `-setnumber R2 2`,
// `-setnumber hc_lower 0.06` (non-matching contact meshes).
SetFactory("OpenCASCADE");
DefineConstant[
  R1 = {1.0, Name "R1"},
  R2 = {1.0, Name "R2"},
  gap = {0.001, Name "gap"},
  h = {0.2, Name "h"},
  hc = {0.04, Name "hc"},
  rc = {0.15, Name "rc"},
  cap = {0.3, Name "cap"}
];
DefineConstant[
  hc_upper = {hc, Name "hc_upper"},
  hc_lower = {hc, Name "hc_lower"}
];
If (gap <= 0)
  Error("two_spheres_tet: gap must be > 0 (got %g)", gap);
  Abort;
EndIf
Mesh.ElementOrder = 1;

zu = gap / 2;    // upper ball's lowest point
zl = -gap / 2;   // lower ball's highest point

// Upper ball, cut at z = zu + cap; the pieces outside the ball are deleted.
Sphere(1) = {0, 0, zu + R1, R1};
Box(2) = {-2 * R1, -2 * R1, zu - R1, 4 * R1, 4 * R1, R1 + cap};
BooleanFragments{ Volume{1}; Delete; }{ Volume{2}; Delete; }
e1 = 1e-6 * R1;
u_cap() = Volume In BoundingBox{-R1 - e1, -R1 - e1, zu - e1, R1 + e1, R1 + e1, zu + cap + e1};
u_rest() = Volume In BoundingBox{-R1 - e1, -R1 - e1, zu + cap - e1, R1 + e1, R1 + e1, zu + 2 * R1 + e1};
outside() = Volume{:};
outside() -= {u_cap(), u_rest()};
Recursive Delete{ Volume{outside()}; }

// Lower ball, cut at z = zl - cap.
Sphere(11) = {0, 0, zl - R2, R2};
Box(12) = {-2 * R2, -2 * R2, zl - cap, 4 * R2, 4 * R2, R2 + cap};
BooleanFragments{ Volume{11}; Delete; }{ Volume{12}; Delete; }
e2 = 1e-6 * R2;
l_cap() = Volume In BoundingBox{-R2 - e2, -R2 - e2, zl - cap - e2, R2 + e2, R2 + e2, zl + e2};
l_rest() = Volume In BoundingBox{-R2 - e2, -R2 - e2, zl - 2 * R2 - e2, R2 + e2, R2 + e2, zl - cap + e2};
outside() = Volume{:};
outside() -= {u_cap(), u_rest(), l_cap(), l_rest()};
Recursive Delete{ Volume{outside()}; }

// Caps' spherical surfaces: every surface of the cap but the flat cut (each box lies on
// its own side of z = 0, so it cannot catch the other ball's surfaces as long as gap > 0).
u_contact() = Surface In BoundingBox{-R1 - e1, -R1 - e1, zu - e1, R1 + e1, R1 + e1, zu + cap + e1};
u_cut() = Surface In BoundingBox{-R1 - e1, -R1 - e1, zu + cap - e1, R1 + e1, R1 + e1, zu + cap + e1};
u_contact() -= u_cut();
u_free() = Surface In BoundingBox{-R1 - e1, -R1 - e1, zu + cap - e1, R1 + e1, R1 + e1, zu + 2 * R1 + e1};
u_free() -= u_cut();
l_contact() = Surface In BoundingBox{-R2 - e2, -R2 - e2, zl - cap - e2, R2 + e2, R2 + e2, zl + e2};
l_cut() = Surface In BoundingBox{-R2 - e2, -R2 - e2, zl - cap - e2, R2 + e2, R2 + e2, zl - cap + e2};
l_contact() -= l_cut();
l_free() = Surface In BoundingBox{-R2 - e2, -R2 - e2, zl - 2 * R2 - e2, R2 + e2, R2 + e2, zl - cap + e2};
l_free() -= l_cut();

// Size fields, each restricted to its ball (entities listed down to the curves).
u_surf() = Abs(Boundary{ Volume{u_cap(), u_rest()}; });
u_curv() = Abs(Boundary{ Surface{u_surf()}; });
l_surf() = Abs(Boundary{ Volume{l_cap(), l_rest()}; });
l_curv() = Abs(Boundary{ Surface{l_surf()}; });
Point(100) = {0, 0, zu};
Point(101) = {0, 0, zl};
Field[1] = Distance;
Field[1].PointsList = {100};
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = hc_upper;
Field[2].SizeMax = h;
Field[2].DistMin = rc;
Field[2].DistMax = rc + 2 * R1 / 3;
Field[3] = Restrict;
Field[3].InField = 2;
Field[3].VolumesList = {u_cap(), u_rest()};
Field[3].SurfacesList = {u_surf()};
Field[3].CurvesList = {u_curv()};
Field[4] = Distance;
Field[4].PointsList = {101};
Field[5] = Threshold;
Field[5].InField = 4;
Field[5].SizeMin = hc_lower;
Field[5].SizeMax = h;
Field[5].DistMin = rc;
Field[5].DistMax = rc + 2 * R2 / 3;
Field[6] = Restrict;
Field[6].InField = 5;
Field[6].VolumesList = {l_cap(), l_rest()};
Field[6].SurfacesList = {l_surf()};
Field[6].CurvesList = {l_curv()};
Field[7] = Min;
Field[7].FieldsList = {3, 6};
Background Field = 7;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;

Physical Surface("upper_contact") = {u_contact()};
Physical Surface("upper_free") = {u_free()};
Physical Surface("lower_contact") = {l_contact()};
Physical Surface("lower_free") = {l_free()};
Physical Volume("upper") = {u_cap(), u_rest()};
Physical Volume("lower") = {l_cap(), l_rest()};
