"""The aided interval of the true window mean ``[x_W]`` (docs/dynamic-method.md, section 3).

One module per true-signal constraint, each the code of one subsection of section 3:

* :mod:`.accel_x`: accel_x from the velocity at the window ends (or the position means);
* :mod:`.positions`: the mean body velocities over fix intervals (positions only);
* :mod:`.accel_y`: accel_y;
* :mod:`.yaw`: gyro_z from the heading (:mod:`.heading`: the yaw rate from the heading
  difference, the heading between its epochs);
* :mod:`.attitude`: gyro_x, gyro_y and accel_z from an attitude stream;
* :mod:`.vehicle`: windows shorter than the aiding period (vehicle bounds only).

Shared pieces: :mod:`.common` (constants, the IMU-side magnitude bounds),
:mod:`.tilt` (roll/pitch functions), :mod:`.velocity` (body velocity at the aiding
epochs and its range over a window), :mod:`.horizontal` (the terms accel_x and accel_y
share), :mod:`.transport` (the bound of the mean |yaw rate|), :mod:`.transport_blocks`
(a gyro centred on blocks: the noise counted once).
"""
