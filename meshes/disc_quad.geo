// Disc of radius R centred at (0, R + gap), just above the plane y = 0: its lowest point
// (0, gap) is where contact starts, so the mesh is refined there (size hc) and coarse (h)
// far away; all quadrilaterals. Override with e.g. `-setnumber hc 0.05 -setnumber gap 0.1`.
DefineConstant[
  R = {8, Name "R"},
  gap = {0.05, Name "gap"},
  h = {1.0, Name "h"},
  hc = {0.1, Name "hc"},
  rc = {0.5, Name "rc"}
];
Mesh.ElementOrder = 1;
// All quadrilaterals: Frontal-Delaunay triangles recombined by the full-quad Blossom
// algorithm (no leftover triangles). Mesh.Algorithm = 8 (Frontal-Delaunay for quads)
// crashes gmsh 4.8.4 (Debian) on this disc, so it is not used.
Mesh.Algorithm = 6;
Mesh.RecombineAll = 1;
Mesh.RecombinationAlgorithm = 3;

yc = R + gap;
s = Sqrt(2) / 2;
Point(1) = {0, yc, 0, h};                // centre
Point(2) = {-R * s, yc - R * s, 0, h};   // 225 deg
Point(3) = {0, gap, 0, hc};              // 270 deg: lowest point
Point(4) = {R * s, yc - R * s, 0, h};    // 315 deg
Point(5) = {0, yc + R, 0, h};            // 90 deg
c80 = Cos(80 * Pi / 180); s80 = Sin(80 * Pi / 180);
Point(6) = {R * c80, yc + R * s80, 0, h};   // 80 deg
Point(7) = {-R * c80, yc + R * s80, 0, h};  // 100 deg
Circle(1) = {2, 1, 3};
Circle(2) = {3, 1, 4};
Circle(3) = {4, 1, 6};
Circle(5) = {6, 1, 5};
Circle(6) = {5, 1, 7};
Circle(4) = {7, 1, 2};
Curve Loop(1) = {1, 2, 3, 5, 6, 4};
Plane Surface(1) = {1};

// Size hc within rc of the lowest point (default 5 hc = 0.5), growing to h at rc + 4 h.
Field[1] = Distance;
Field[1].PointsList = {3};
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = hc;
Field[2].SizeMax = h;
Field[2].DistMin = rc;
Field[2].DistMax = rc + 4 * h;
Background Field = 2;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;

Physical Curve("contact") = {1, 2};   // lower quarter, 225..315 deg
Physical Curve("free") = {3, 4};     // the rest of the circle but the top
Physical Curve("top") = {5, 6};      // 80..100 deg: where a disc can be held or pushed
Recombine Surface{1};
Physical Surface("disc") = {1};
