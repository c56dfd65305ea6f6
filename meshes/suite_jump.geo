// A W x H block on (0, W) x (0, H) whose cells jump in size: quadrilaterals of size hc in a
// band of height b along the bottom (the contact side) and of size h = jump * hc above it,
// with the change made within one fine cell (gmsh's Threshold field from hc below y = b to h
// above y = b + hc). All quadrilaterals: Frontal-Delaunay triangles of twice those sizes,
// recombined (Blossom) and then each cell split into quadrilaterals (SubdivisionAlgorithm 1),
// since Blossom alone leaves a triangle when their number is odd.
//   Physical surface: "body".   Physical curves: "bottom", "right", "top", "left".
// Override with e.g. `-setnumber hc 0.01 -setnumber jump 10`.
DefineConstant[
  W = {1, Name "W"},
  H = {1, Name "H"},
  hc = {0.02, Name "hc"},
  jump = {10, Name "jump"},
  b = {0.1, Name "b"}
];
Mesh.ElementOrder = 1;
Mesh.Algorithm = 6;
Mesh.RecombineAll = 1;
Mesh.RecombinationAlgorithm = 3;
Mesh.SubdivisionAlgorithm = 1;

Point(1) = {0, 0, 0}; Point(2) = {W, 0, 0}; Point(3) = {W, H, 0}; Point(4) = {0, H, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};

Field[1] = Distance;
Field[1].CurvesList = {1};
Field[1].NumPointsPerCurve = 400;
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = 2 * hc;
Field[2].SizeMax = 2 * jump * hc;
Field[2].DistMin = b;
Field[2].DistMax = b + hc;
Background Field = 2;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
Recombine Surface{1};

Physical Curve("bottom") = {1};
Physical Curve("right") = {2};
Physical Curve("top") = {3};
Physical Curve("left") = {4};
Physical Surface("body") = {1};
