// Cylindrical billet for the upsetting scene (upsetting.toml): the r-z
// section [0, 15] x [0, 33.6] mm, quadrilaterals of about 2 mm, finer
// (1.2 mm) at the outer corners where the billet folds onto the tools.
h = 2.0;
hc = 1.2;
R = 15.0;
H = 33.6;
Point(1) = {0, 0, 0, h};
Point(2) = {R, 0, 0, hc};
Point(3) = {R, H, 0, hc};
Point(4) = {0, H, 0, h};
Line(1) = {1, 2};
Line(2) = {2, 3};
Line(3) = {3, 4};
Line(4) = {4, 1};
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Physical Curve("bottom") = {1};
Physical Curve("right") = {2};
Physical Curve("top") = {3};
Physical Curve("left") = {4};
Physical Surface("billet") = {1};
Mesh.Algorithm = 8;
Mesh.RecombineAll = 1;
Mesh.RecombinationAlgorithm = 3;
