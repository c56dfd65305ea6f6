// A W x H block of structured quadrilaterals on (0, W) x (0, H) for the stability suite
// (scenes/suite/): nx = W / h columns and ny rows. The rows are uniform (height H / ny) unless
// `ar` asks for thinner cells at the bottom (the contact side): then the rows grow
// geometrically upwards from a bottom row of height h / ar, i.e. cells with aspect ratio
// 1 : ar at the contact boundary (the growth factor r solves h/ar (r^ny - 1)/(r - 1) = H).
//   Physical surface: "body".
//   Physical curves:  "bottom", "right", "top", "left", "sides" (left and right together).
// Override with e.g. `-setnumber h 0.05 -setnumber ny 20 -setnumber ar 20`.
DefineConstant[
  W = {1, Name "W"},
  H = {1, Name "H"},
  h = {0.1, Name "h"},
  ny = {0, Name "ny"},          // 0: Round(H / h)
  ar = {0, Name "ar"}           // 0: uniform rows
];
Mesh.ElementOrder = 1;

nx = Round(W / h);
rows = ny;
If (rows < 1)
  rows = Round(H / h);
EndIf
// Growth factor of the rows: S = H / (h / ar) cells of the bottom height fill the block.
r = 1;
If (ar > 0)
  S = H * ar / h;
  If (S > rows * (1 + 1e-9))
    lo = 1 + 1e-12; hi = 4;
    For k In {1:200}
      mid = (lo + hi) / 2;
      F = (mid^rows - 1) / (mid - 1) - S;
      If (F > 0)
        hi = mid;
      Else
        lo = mid;
      EndIf
    EndFor
    r = (lo + hi) / 2;
  EndIf
EndIf

Point(1) = {0, 0, 0}; Point(2) = {W, 0, 0}; Point(3) = {W, H, 0}; Point(4) = {0, H, 0};
Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {4, 3}; Line(4) = {1, 4};
Curve Loop(1) = {1, 2, -3, -4};
Plane Surface(1) = {1};

Transfinite Curve{1, 3} = nx + 1;
Transfinite Curve{2, 4} = rows + 1 Using Progression r;   // both upwards: thin rows at y = 0
Transfinite Surface{1};
Recombine Surface{1};

Physical Curve("bottom") = {1};
Physical Curve("right") = {2};
Physical Curve("top") = {3};
Physical Curve("left") = {4};
Physical Curve("sides") = {2, 4};
Physical Surface("body") = {1};
