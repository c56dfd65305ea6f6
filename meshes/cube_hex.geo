// Unit cube (0,1)^3: structured hexahedra of size h (small 3D test body), made by extruding
// a recombined transfinite square in z. Override with `-setnumber h 0.125`.
DefineConstant[ h = {0.25, Name "h"} ];
Mesh.ElementOrder = 1;

Point(1) = {0, 0, 0}; Point(2) = {1, 0, 0}; Point(3) = {1, 1, 0}; Point(4) = {0, 1, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Transfinite Curve{1, 2, 3, 4} = Round(1 / h) + 1;
Transfinite Surface{1};
Recombine Surface{1};

// out[0] = top (z = 1), out[1] = volume, out[2..5] = sides swept from lines 1..4.
out[] = Extrude {0, 0, 1} { Surface{1}; Layers{Round(1 / h)}; Recombine; };

Physical Surface("bottom") = {1};
Physical Surface("top") = {out[0]};
Physical Surface("front") = {out[2]};
Physical Surface("right") = {out[3]};
Physical Surface("back") = {out[4]};
Physical Surface("left") = {out[5]};
Physical Volume("body") = {out[1]};
