// Structured quad grid on a disc (the circular MRA grid shells): four arcs at -135, -45,
// 45 and 135 degrees are the four sides of one transfinite patch, so both families of
// grid lines end on the rim.
// gmsh disk.geo -2      shellform: shellform.geometry.disk_grid(R, n)
DefineConstant[ R = {10.0, Name "radius"}, n = {24, Name "quads per side"} ];
Point(1) = {0, 0, 0};
Point(2) = {R * Cos(-3 * Pi / 4), R * Sin(-3 * Pi / 4), 0};
Point(3) = {R * Cos(-Pi / 4), R * Sin(-Pi / 4), 0};
Point(4) = {R * Cos(Pi / 4), R * Sin(Pi / 4), 0};
Point(5) = {R * Cos(3 * Pi / 4), R * Sin(3 * Pi / 4), 0};
Circle(1) = {2, 1, 3};  // south
Circle(2) = {3, 1, 4};  // east
Circle(3) = {4, 1, 5};  // north
Circle(4) = {5, 1, 2};  // west
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Transfinite Curve{1, 2, 3, 4} = n + 1;
Transfinite Surface{1} = {2, 3, 4, 5};
Recombine Surface{1};
Physical Curve("rim") = {1, 2, 3, 4};
Physical Surface("net") = {1};
