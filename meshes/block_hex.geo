// Block (0,10)x(0,1)x(0,1): structured hexahedra of size h, made by extruding a
// recombined transfinite rectangle in z. Override with `-setnumber h 0.125`.
DefineConstant[ h = {0.25, Name "h"} ];
Mesh.ElementOrder = 1;

L = 10; W = 1; H = 1;
Point(1) = {0, 0, 0}; Point(2) = {L, 0, 0}; Point(3) = {L, W, 0}; Point(4) = {0, W, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Transfinite Curve{1, 3} = Round(L / h) + 1;
Transfinite Curve{2, 4} = Round(W / h) + 1;
Transfinite Surface{1};
Recombine Surface{1};

// out[0] = top (z = H), out[1] = volume, out[2..5] = sides swept from lines 1..4.
out[] = Extrude {0, 0, H} { Surface{1}; Layers{Round(H / h)}; Recombine; };

Physical Surface("bottom") = {1};
Physical Surface("top") = {out[0]};
Physical Surface("front") = {out[2]};
Physical Surface("right") = {out[3]};
Physical Surface("back") = {out[4]};
Physical Surface("left") = {out[5]};
Physical Volume("body") = {out[1]};
