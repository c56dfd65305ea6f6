// Block (0,L)x(0,1) for ironing at depth: structured quadrilaterals of size h.
DefineConstant[ h = {0.0625, Name "h"}, L = {3, Name "L"} ];
Mesh.ElementOrder = 1;

H = 1;
Point(1) = {0, 0, 0}; Point(2) = {L, 0, 0}; Point(3) = {L, H, 0}; Point(4) = {0, H, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};

Transfinite Curve{1, 3} = Round(L / h) + 1;
Transfinite Curve{2, 4} = Round(H / h) + 1;
Transfinite Surface{1};
Recombine Surface{1};

Physical Curve("bottom") = {1};
Physical Curve("right") = {2};
Physical Curve("top") = {3};
Physical Curve("left") = {4};
Physical Surface("body") = {1};
