// A cylindrical triaxial sample for `hmm run examples/triaxial_cylinder.toml`:
// radius R and height H along y, meshed with hexahedra (an O-grid of five blocks
// extruded in layers). Its physical groups name the boundaries the problem file uses.
//   gmsh -3 -format msh22 examples/triaxial_cylinder.geo -o examples/triaxial_cylinder.msh
// The problem's [mesh] element = "hex20" makes quadratic elements of these hexahedra.
R = 0.025;      // [m] radius
H = 0.1;        // [m] height
a = 0.45 * R;   // half side of the central square block
n = 2;          // cells along a side of the square, and around each quarter of the rim
nr = 1;         // cells from the square to the rim
nh = 4;         // cells along the height

Point(1) = {0, 0, 0};
Point(2) = {a, 0, a};
Point(3) = {-a, 0, a};
Point(4) = {-a, 0, -a};
Point(5) = {a, 0, -a};
c = R / Sqrt(2);
Point(6) = {c, 0, c};
Point(7) = {-c, 0, c};
Point(8) = {-c, 0, -c};
Point(9) = {c, 0, -c};
Line(1) = {2, 3};
Line(2) = {3, 4};
Line(3) = {4, 5};
Line(4) = {5, 2};
Circle(5) = {6, 1, 7};
Circle(6) = {7, 1, 8};
Circle(7) = {8, 1, 9};
Circle(8) = {9, 1, 6};
Line(9) = {2, 6};
Line(10) = {3, 7};
Line(11) = {4, 8};
Line(12) = {5, 9};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Curve Loop(2) = {9, 5, -10, -1};
Plane Surface(2) = {2};
Curve Loop(3) = {10, 6, -11, -2};
Plane Surface(3) = {3};
Curve Loop(4) = {11, 7, -12, -3};
Plane Surface(4) = {4};
Curve Loop(5) = {12, 8, -9, -4};
Plane Surface(5) = {5};
Transfinite Curve {1:8} = n + 1;
Transfinite Curve {9:12} = nr + 1;
Transfinite Surface {1:5};
Recombine Surface {1:5};

// each extruded surface gives [its top, its volume, a side per curve of its loop]
out[] = Extrude {0, H, 0} { Surface{1:5}; Layers{nh}; Recombine; };

Physical Surface("bottom") = {1:5};
Physical Surface("top") = {out[0], out[6], out[12], out[18], out[24]};
Physical Surface("side") = {out[9], out[15], out[21], out[27]};
Physical Volume("sample") = {out[1], out[7], out[13], out[19], out[25]};
