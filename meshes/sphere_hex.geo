// The ball of sphere_tet.geo in hexahedra: tetrahedra of size hc within rc of the lowest point
// (0, 0, gap) (where contact starts), growing to h at rc + 2 R / 3, each split into 4
// hexahedra (so hexahedra of about half those sizes). The lower cap (z < gap + cap) is the
// physical surface "contact". Override with e.g. `-setnumber hc 0.04 -setnumber h 0.2`.
SetFactory("OpenCASCADE");
DefineConstant[
  R = {1.0, Name "R"},
  gap = {0.001, Name "gap"},
  h = {0.4, Name "h"},
  hc = {0.08, Name "hc"},
  rc = {0.15, Name "rc"},
  cap = {0.3, Name "cap"}
];
Mesh.ElementOrder = 1;
Mesh.SubdivisionAlgorithm = 2;   // every tetrahedron split into 4 hexahedra

Sphere(1) = {0, 0, R + gap, R};
Box(2) = {-2 * R, -2 * R, gap - R, 4 * R, 4 * R, R + cap};
BooleanFragments{ Volume{1}; Delete; }{ Volume{2}; Delete; }
e = 1e-6 * R;
low() = Volume In BoundingBox{-R - e, -R - e, gap - e, R + e, R + e, gap + cap + e};
high() = Volume In BoundingBox{-R - e, -R - e, gap + cap - e, R + e, R + e, gap + 2 * R + e};
outside() = Volume{:};
outside() -= {low(), high()};
Recursive Delete{ Volume{outside()}; }

// The cap's spherical surface: every surface of the lower part but the flat cut.
contact() = Surface In BoundingBox{-R - e, -R - e, gap - e, R + e, R + e, gap + cap + e};
cut() = Surface In BoundingBox{-R - e, -R - e, gap + cap - e, R + e, R + e, gap + cap + e};
contact() -= cut();
rest() = Surface In BoundingBox{-R - e, -R - e, gap + cap - e, R + e, R + e, gap + 2 * R + e};
rest() -= cut();

Point(100) = {0, 0, gap};
Field[1] = Distance;
Field[1].PointsList = {100};
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = hc;
Field[2].SizeMax = h;
Field[2].DistMin = rc;
Field[2].DistMax = rc + 2 * R / 3;
Background Field = 2;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;

Physical Surface("contact") = {contact()};
Physical Surface("free") = {rest()};
Physical Volume("ball") = {low(), high()};
