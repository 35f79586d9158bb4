// Ring compression, quarter section (r from 30 to 60 mm, z from 0 to 20 mm)
// with 16 x 11 particles graded toward the contact face and its two corners,
// where the free surfaces fold onto the platen (Chen et al. 1998, Fig. 16-17).
Point(1) = {30, 0, 0};
Point(2) = {60, 0, 0};
Point(3) = {60, 20, 0};
Point(4) = {30, 20, 0};
Line(1) = {1, 2};   // mid-height symmetry plane
Line(2) = {2, 3};   // outer surface
Line(3) = {3, 4};   // contact face
Line(4) = {4, 1};   // inner surface
Curve Loop(1) = {1, 2, 3, 4};
Plane Surface(1) = {1};
Transfinite Curve {1, 3} = 16 Using Bump 0.35;      // denser at both radial ends
Transfinite Curve {2} = 11 Using Progression 0.88;  // denser toward the top
Transfinite Curve {4} = 11 Using Progression 1 / 0.88;
Transfinite Surface {1};
Recombine Surface {1};
Physical Curve("bottom") = {1};
Physical Curve("right") = {2};
Physical Curve("top") = {3};
Physical Curve("left") = {4};
Physical Surface("ring") = {1};
