// The L-shaped block of Simo and Tarnow (1992): the union of (0,6)x(0,3)x(0,3) and
// (0,3)x(0,10)x(0,3), structured hexahedra of size h (three transfinite rectangles in the
// xy-plane, recombined and extruded in z). The end faces of its arms, x = 6 and y = 10, carry
// the loads of the free-flight benchmark. Override with `-setnumber h 0.5`.
DefineConstant[ h = {1.0, Name "h"} ];
Mesh.ElementOrder = 1;

Point(1) = {0, 0, 0}; Point(2) = {3, 0, 0}; Point(3) = {6, 0, 0}; Point(4) = {6, 3, 0};
Point(5) = {3, 3, 0}; Point(6) = {0, 3, 0}; Point(7) = {3, 10, 0}; Point(8) = {0, 10, 0};
Line(1) = {1, 2}; Line(2) = {2, 5}; Line(3) = {5, 6}; Line(4) = {6, 1};   // corner square
Line(5) = {2, 3}; Line(6) = {3, 4}; Line(7) = {4, 5};                     // arm along x
Line(8) = {5, 7}; Line(9) = {7, 8}; Line(10) = {8, 6};                    // arm along y
Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};
Curve Loop(2) = {5, 6, 7, -2}; Plane Surface(2) = {2};
Curve Loop(3) = {-3, 8, 9, 10}; Plane Surface(3) = {3};
Transfinite Curve{1, 2, 3, 4, 5, 6, 7, 9} = Round(3 / h) + 1;
Transfinite Curve{8, 10} = Round(7 / h) + 1;
Transfinite Surface{1, 2, 3};
Recombine Surface{1, 2, 3};

e1[] = Extrude {0, 0, 3} { Surface{1}; Layers{Round(3 / h)}; Recombine; };
e2[] = Extrude {0, 0, 3} { Surface{2}; Layers{Round(3 / h)}; Recombine; };
e3[] = Extrude {0, 0, 3} { Surface{3}; Layers{Round(3 / h)}; Recombine; };

// e2[3] is swept from line 6 (x = 6), e3[4] from line 9 (y = 10).
Physical Surface("end_x") = {e2[3]};
Physical Surface("end_y") = {e3[4]};
Physical Surface("bottom") = {1, 2, 3};
Physical Volume("body") = {e1[1], e2[1], e3[1]};
