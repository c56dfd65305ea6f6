// Two-disc impact (Hager & Wohlmuth 2009, sect. 7.2), all quadrilaterals: two discs of
// radius R, the upper one centred at (0, R + gap/2) and the lower one at (0, -(R + gap/2)),
// so they are symmetric about y = 0 with a gap `gap` between their closest points
// (0, +-gap/2). Each disc is refined near its contact point (size hc_upper / hc_lower within
// rc, growing to h at rc + 4 h, as in disc_quad.geo). The bodies are separate surfaces with
// no shared node.
//   Physical surfaces: "upper", "lower".
//   Physical curves:   "upper_contact" (225..315 deg), "upper_free", "upper_top" (80..100 deg),
//                      "lower_contact" (45..135 deg),  "lower_free", "lower_bottom" (260..280).
// mirror = 1 (the default when hc_upper == hc_lower): the lower disc's mesh is the exact mirror
// image of the upper's about y = 0, node for node (x, y) -> (x, -y); it is made by a one-layer
// structured extrusion of the upper disc rotated by Pi about the x-axis, whose end face carries
// a node-by-node copy of the upper mesh (the lower nodes have |z| ~ 1e-15, from sin(Pi)).
// mirror = 0: the lower disc is meshed on its own (non-matching meshes when hc_upper != hc_lower).
// Override with e.g. `-setnumber hc 0.05`, `-setnumber hc_lower 0.2` (then mirror = 0),
// `-setnumber mirror 0`, `-setnumber gap 0.2 -setnumber h 2`.
SetFactory("OpenCASCADE");
DefineConstant[
  R = {8, Name "R"},
  gap = {0.1, Name "gap"},
  h = {1.0, Name "h"},
  hc = {0.1, Name "hc"},
  rc = {0.5, Name "rc"}
];
DefineConstant[
  hc_upper = {hc, Name "hc_upper"},
  hc_lower = {hc, Name "hc_lower"}
];
DefineConstant[ mirror = {(hc_upper == hc_lower) ? 1 : 0, Name "mirror"} ];
If (mirror && hc_upper != hc_lower)
  Error("two_discs: mirror = 1 needs hc_upper == hc_lower (got %g, %g)", hc_upper, hc_lower);
  Abort;
EndIf
If (gap <= 0)
  Error("two_discs: gap must be > 0 (got %g)", gap);
  Abort;
EndIf
Mesh.ElementOrder = 1;
// All quadrilaterals: Frontal-Delaunay triangles recombined by the full-quad Blossom
// algorithm (no leftover triangles). Mesh.Algorithm = 8 crashes gmsh 4.8.4 on discs.
Mesh.Algorithm = 6;
Mesh.RecombineAll = 1;
Mesh.RecombinationAlgorithm = 3;

yc = R + gap / 2;
s = Sqrt(2) / 2;
c80 = Cos(80 * Pi / 180); s80 = Sin(80 * Pi / 180);
e = 1e-6 * R;

// Upper disc (the slave side).
Point(1) = {0, yc, 0, h};                    // centre
Point(2) = {-R * s, yc - R * s, 0, h};       // 225 deg
Point(3) = {0, gap / 2, 0, hc_upper};        // 270 deg: contact point
Point(4) = {R * s, yc - R * s, 0, h};        // 315 deg
Point(5) = {0, yc + R, 0, h};                // 90 deg
Point(6) = {R * c80, yc + R * s80, 0, h};    // 80 deg
Point(7) = {-R * c80, yc + R * s80, 0, h};   // 100 deg
Circle(1) = {2, 1, 3};
Circle(2) = {3, 1, 4};
Circle(3) = {4, 1, 6};
Circle(5) = {6, 1, 5};
Circle(6) = {5, 1, 7};
Circle(4) = {7, 1, 2};
Curve Loop(1) = {1, 2, 3, 5, 6, 4};
Plane Surface(1) = {1};
Recombine Surface{1};

If (mirror)
  // Rotating the upper disc by Pi about the x-axis maps (x, y, 0) to (x, -y, 0); the end face
  // of this one-layer extrusion gets a copy of the upper mesh (the swept volume and side faces
  // are not in any physical group, so they are not saved). The copy keeps the node order, so
  // its elements are reversed to be counter-clockwise again.
  ext[] = Extrude { {1, 0, 0}, {0, 0, 0}, Pi } { Surface{1}; Layers{1}; Recombine; };
  lower = ext[0];
  ReverseMesh Surface{lower};
Else
  Point(11) = {0, -yc, 0, h};                  // centre
  Point(12) = {-R * s, -yc + R * s, 0, h};     // 135 deg
  Point(13) = {0, -gap / 2, 0, hc_lower};      // 90 deg: contact point
  Point(14) = {R * s, -yc + R * s, 0, h};      // 45 deg
  Point(15) = {0, -yc - R, 0, h};              // 270 deg
  Point(16) = {R * c80, -yc - R * s80, 0, h};  // 280 deg
  Point(17) = {-R * c80, -yc - R * s80, 0, h}; // 260 deg
  // Arcs in counter-clockwise direction (OpenCASCADE orients the face, hence the mesh, by them).
  Circle(11) = {14, 11, 13};   // 45..90 deg
  Circle(12) = {13, 11, 12};   // 90..135 deg
  Circle(13) = {12, 11, 17};   // 135..260 deg
  Circle(15) = {17, 11, 15};   // 260..270 deg
  Circle(16) = {15, 11, 16};   // 270..280 deg
  Circle(14) = {16, 11, 14};   // 280..405 deg
  Curve Loop(2) = {11, 12, 13, 15, 16, 14};
  Plane Surface(2) = {2};
  Recombine Surface{2};
  lower = 2;
EndIf

// Lower disc's boundary curves, found by bounding box (in the plane z = 0 only: the side
// faces of the mirror extrusion leave the plane).
lower_all() = Curve In BoundingBox{-R - e, -yc - R - e, -e, R + e, -gap / 2 + e, e};
lower_contact() = Curve In BoundingBox{-R * s - e, -yc + R * s - e, -e, R * s + e, -gap / 2 + e, e};
lower_bottom() = Curve In BoundingBox{-R * c80 - e, -yc - R - e, -e, R * c80 + e, -yc - R * s80 + e, e};
lower_free() = lower_all();
lower_free() -= {lower_contact(), lower_bottom()};

// Size hc_upper within rc of the upper contact point, growing to h at rc + 4 h; each disc's
// field is restricted to that disc so that the two zones (gap apart) do not mix.
Field[1] = Distance;
Field[1].PointsList = {3};
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = hc_upper;
Field[2].SizeMax = h;
Field[2].DistMin = rc;
Field[2].DistMax = rc + 4 * h;
Field[3] = Restrict;
Field[3].InField = 2;
Field[3].SurfacesList = {1};
Field[3].CurvesList = {1, 2, 3, 4, 5, 6};
If (mirror)
  Background Field = 3;
Else
  Field[4] = Distance;
  Field[4].PointsList = {13};
  Field[5] = Threshold;
  Field[5].InField = 4;
  Field[5].SizeMin = hc_lower;
  Field[5].SizeMax = h;
  Field[5].DistMin = rc;
  Field[5].DistMax = rc + 4 * h;
  Field[6] = Restrict;
  Field[6].InField = 5;
  Field[6].SurfacesList = {2};
  Field[6].CurvesList = {11, 12, 13, 14, 15, 16};
  Field[7] = Min;
  Field[7].FieldsList = {3, 6};
  Background Field = 7;
EndIf
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;

Physical Surface("upper") = {1};
Physical Surface("lower") = {lower};
Physical Curve("upper_contact") = {1, 2};   // 225..315 deg
Physical Curve("upper_free") = {3, 4};      // the rest of the circle but the top
Physical Curve("upper_top") = {5, 6};       // 80..100 deg: where the disc can be held or pushed
Physical Curve("lower_contact") = {lower_contact()};  // 45..135 deg
Physical Curve("lower_free") = {lower_free()};
Physical Curve("lower_bottom") = {lower_bottom()};    // 260..280 deg
