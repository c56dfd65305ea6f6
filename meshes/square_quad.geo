// Unit square (0,1)x(0,1): structured quadrilaterals of size h (small test mesh).
DefineConstant[ h = {0.25, Name "h"} ];
Mesh.ElementOrder = 1;

Point(1) = {0, 0, 0}; Point(2) = {1, 0, 0}; Point(3) = {1, 1, 0}; Point(4) = {0, 1, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};

Transfinite Curve{1, 2, 3, 4} = Round(1 / h) + 1;
Transfinite Surface{1};
Recombine Surface{1};

Physical Curve("bottom") = {1};
Physical Curve("right") = {2};
Physical Curve("top") = {3};
Physical Curve("left") = {4};
Physical Surface("body") = {1};
