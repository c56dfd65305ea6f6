// Cattaneo-Mindlin partial slip, 2D: a half-cylinder (the lower half of a disc of
// radius R, flat side up at y = gap + R) resting on a block [-W, W] x [-H, 0]. Separate
// surfaces with separate nodes; the cells are of size hc within rc of the contact point
// (0, 0) on both bodies, growing to h away from it (quadrilaterals).
//   Physical surfaces: "cylinder", "block".
//   Physical curves:   "cylinder_contact" (the arc within 30 degrees of the lowest point),
//                      "cylinder_top" (the flat side), "cylinder_free" (the rest of the arc),
//                      "block_top", "block_bottom", "block_sides".
DefineConstant[
  R = {4, Name "R"}, W = {4, Name "W"}, H = {4, Name "H"}, gap = {0.001, Name "gap"},
  h = {0.5, Name "h"}, hc = {0.025, Name "hc"}, rc = {1.0, Name "rc"}
];
Mesh.ElementOrder = 1;
Mesh.Algorithm = 6;
Mesh.RecombineAll = 1;
Mesh.RecombinationAlgorithm = 3;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;

yc = gap + R;
s30 = Sin(30 * Pi / 180); c30 = Cos(30 * Pi / 180);

// Block: corners, and the top split at the contact point.
Point(1) = {-W, -H, 0}; Point(2) = {W, -H, 0}; Point(3) = {W, 0, 0}; Point(4) = {0, 0, 0};
Point(5) = {-W, 0, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 5}; Line(5) = {5, 1};
Curve Loop(1) = {1, 2, 3, 4, 5};
Plane Surface(1) = {1};

// Half-cylinder: centre, the ends of the flat side, the contact arc's ends and lowest point.
Point(10) = {0, yc, 0};
Point(11) = {-R, yc, 0}; Point(12) = {R, yc, 0};
Point(13) = {-R * s30, yc - R * c30, 0}; Point(14) = {0, gap, 0};
Point(15) = {R * s30, yc - R * c30, 0};
Circle(11) = {11, 10, 13};   // free, left
Circle(12) = {13, 10, 14};   // contact, left
Circle(13) = {14, 10, 15};   // contact, right
Circle(14) = {15, 10, 12};   // free, right
Line(15) = {12, 11};         // flat top
Curve Loop(2) = {11, 12, 13, 14, 15};
Plane Surface(2) = {2};

// Sizes: hc near the contact point, h far away.
Field[1] = Distance;
Field[1].PointsList = {4, 14};
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = hc;
Field[2].SizeMax = h;
Field[2].DistMin = rc;
Field[2].DistMax = rc + 8 * h;
Background Field = 2;

Physical Surface("cylinder") = {2};
Physical Surface("block") = {1};
Physical Curve("cylinder_contact") = {12, 13};
Physical Curve("cylinder_top") = {15};
Physical Curve("cylinder_free") = {11, 14};
Physical Curve("block_top") = {3, 4};
Physical Curve("block_bottom") = {1};
Physical Curve("block_sides") = {2, 5};
