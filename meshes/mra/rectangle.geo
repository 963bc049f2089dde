// Structured quad grid on a rectangle (the planform of the 9 x 4 MRA net).
// gmsh rectangle.geo -2 -format msh4   (or: gmsh rectangle.geo -setnumber nx 120 ... -2)
// shellform builds the same grid in Python: shellform.geometry.rectangle_grid(Lx, Ly, nx, ny).
DefineConstant[ Lx = {9.0, Name "length x"}, Ly = {4.0, Name "length y"},
                nx = {9, Name "quads along x"}, ny = {4, Name "quads along y"} ];
Point(1) = {0, 0, 0};
Point(2) = {Lx, 0, 0};
Point(3) = {Lx, Ly, 0};
Point(4) = {0, Ly, 0};
Line(1) = {1, 2};   // south
Line(2) = {2, 3};   // east
Line(3) = {3, 4};   // north
Line(4) = {4, 1};   // west
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Transfinite Curve{1, 3} = nx + 1;
Transfinite Curve{2, 4} = ny + 1;
Transfinite Surface{1} = {1, 2, 3, 4};
Recombine Surface{1};
Physical Curve("south") = {1};
Physical Curve("east") = {2};
Physical Curve("north") = {3};
Physical Curve("west") = {4};
Physical Point("corners") = {1, 2, 3, 4};
Physical Surface("net") = {1};
