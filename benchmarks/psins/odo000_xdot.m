function xd = odo000_xdot(x, p)
% Continuous-time error dynamics of paper 000's odometer-aided large-heading model,
% written from ALGORITHMS 4.1-4.4 in their exact (not first-order) Euler-angle form.
%   x = [phi_E phi_N phi_U, dv(3), dL dlambda dh, eps(3), nabla(3), dK_D (, theta_m psi_m)]
%   phi: Euler angles of the computed frame n', C_n'^n = Rz(U) Rx(E) Ry(N) = a2mat(phi)
%   (PSINS att order [pitch; roll; yaw] = [E; N; U]).
% p: per-epoch INS quantities (n' frame): win (omega_in^n, rad/s), fn (specific force,
%   m/s^2), Cbn (mean C_b^n' over the epoch), v (m/s ENU), lat (rad), h (m), RMh, RNh (m),
%   wie (earth rate, rad/s).
% Attitude: with w the rate of n' relative to n in n',
%   C_dot = C [w x],  w = (I - C') win + C' dwin - Cbn eps,   phi_dot = Cw(phi) \ w,
%   Cw = [Ry' e_x, e_y, Ry' Rx' e_z] (the Euler-rate matrix of the Z-X-Y sequence).
% Velocity: dv_dot = (I - C) fn + C Cbn nabla - (2 wie_n + wen) x dv - (2 dwie + dwen) x v.
% Position: the usual linearised latitude / longitude / height error rates.
  n = numel(x);
  phi = x(1:3); dv = x(4:6); dL = x(7); dh = x(9);
  ep = x(10:12); na = x(13:15);
  C = a2mat(phi);                                  % PSINS: C_n'^n
  sE = sin(phi(1)); cE = cos(phi(1)); sN = sin(phi(2)); cN = cos(phi(2));
  Cw = [cN, 0, -sN*cE; 0, 1, sE; sN, 0, cN*cE];
  lat = p.lat; sl = sin(lat); cl = cos(lat); tl = sl/cl;
  vE = p.v(1); vN = p.v(2);
  RMh = p.RMh; RNh = p.RNh;
  % errors of the computed rates (computed - true), from dp = computed - true
  dwie = [0; -p.wie*sl*dL; p.wie*cl*dL];
  dwen = [-dv(2)/RMh + vN*dh/RMh^2;
           dv(1)/RNh - vE*dh/RNh^2;
           tl*dv(1)/RNh + vE*dL/(cl^2*RNh) - vE*tl*dh/RNh^2];
  w = (eye(3) - C')*p.win + C'*(dwie + dwen) - p.Cbn*ep;
  phid = Cw \ w;
  wie_n = [0; p.wie*cl; p.wie*sl];
  wen = p.win - wie_n;
  dvd = (eye(3) - C)*p.fn + C*(p.Cbn*na) - cross(2*wie_n + wen, dv) ...
        - cross(2*dwie + dwen, p.v);
  dpd = [dv(2)/RMh - vN*dh/RMh^2;
         dv(1)/(cl*RNh) + vE*tl*dL/(cl*RNh) - vE*dh/(cl*RNh^2);
         dv(3)];
  xd = zeros(n, 1);
  xd(1:3) = phid; xd(4:6) = dvd; xd(7:9) = dpd;
end
