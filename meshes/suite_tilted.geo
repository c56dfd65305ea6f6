// A square of side a rotated by `angle` degrees (0 < angle < 90), structured quadrilaterals of
// size h, placed so that its lowest corner is at (0, gap): the corner hits the plane y = 0
// first. dim = 3 extrudes it along z by a (structured hexahedra): a prism whose lowest edge
// (along z) hits first.
//   Physical surface (dim 2) / volume (dim 3): "body".
//   Physical curves (dim 2) / surfaces (dim 3): "low" (the two sides that meet at the lowest
//   corner or edge), "high" (the other two).
// Override with e.g. `-setnumber angle 10 -setnumber h 0.05 -setnumber dim 3`.
DefineConstant[
  a = {1, Name "a"},
  angle = {30, Name "angle"},
  h = {0.1, Name "h"},
  gap = {0, Name "gap"},
  dim = {2, Name "dim"}
];
Mesh.ElementOrder = 1;

th = angle * Pi / 180;
c = Cos(th); s = Sin(th);
// Corners of (-a/2, a/2)^2 rotated by th; the first, (-a/2, -a/2), is the lowest for
// 0 < angle < 90 (for angle >= 45 tie-breaking aside).
x1 = -a/2 * c + a/2 * s;  y1 = -a/2 * s - a/2 * c;
x2 =  a/2 * c + a/2 * s;  y2 =  a/2 * s - a/2 * c;
x3 =  a/2 * c - a/2 * s;  y3 =  a/2 * s + a/2 * c;
x4 = -a/2 * c - a/2 * s;  y4 = -a/2 * s + a/2 * c;
dx = -x1; dy = gap - y1;
Point(1) = {x1 + dx, y1 + dy, 0};
Point(2) = {x2 + dx, y2 + dy, 0};
Point(3) = {x3 + dx, y3 + dy, 0};
Point(4) = {x4 + dx, y4 + dy, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
n = Round(a / h);
Transfinite Curve{1, 2, 3, 4} = n + 1;
Transfinite Surface{1};
Recombine Surface{1};

If (dim == 3)
  // out[0] = the far face, out[1] = the volume, out[2..5] = the sides swept from lines 1..4.
  out[] = Extrude {0, 0, a} { Surface{1}; Layers{n}; Recombine; };
  Physical Surface("low") = {out[2], out[5]};
  Physical Surface("high") = {out[3], out[4]};
  Physical Volume("body") = {out[1]};
Else
  Physical Curve("low") = {1, 4};
  Physical Curve("high") = {2, 3};
  Physical Surface("body") = {1};
EndIf
