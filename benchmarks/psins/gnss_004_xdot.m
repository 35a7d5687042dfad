function xd = gnss_004_xdot(x, q)
% Continuous-time error dynamics of paper 004's classic large-angle model, (6.1), (6.2),
% (6.5) of ALGORITHMS 6 (estimators.rotation_vector_dynamics.classic_derivative), exact
% in the rotation vector and in the rate differences (no linearisation).
%   x = [phi (3), dv (3), dp = (dL, dlambda, dh), eps (3), nabla (3)]; C_p^n = rv2m(phi)
%   (p: the INS's frame; true C_b^n = rv2m(phi) C_b^p, PSINS's qdelphi convention),
%   dv = v~ - v, dp = p~ - p, eps and nabla the gyro drift and accelerometer bias, IMU frame.
% q: the INS's quantities at one instant: Cbp (3x3), fb (3x1, m/s^2, bias compensated),
%   v (3x1, m/s ENU), pos = [lat; lon; h] (rad, rad, m).
%   phi_dot = J_r(phi)^-1 [w_in~ - C_n^p w_in - C_b^p eps],
%   dv_dot  = f~ - C_p^n f~ + C_p^n C_b^p nabla - (2 w_ie~ + w_en~) x v~
%             + (2 w_ie + w_en) x v + g~ - g,    (f~ = C_b^p fb)
%   dp_dot  = rate(p~, v~) - rate(p, v),
% the true quantities (no tilde) at the true position p~ - dp and velocity v~ - dv; the
% earth's rates and gravity from PSINS's earth(); J_r(phi) = J_l(-phi) from PSINS's rv2J.
  phi = x(1:3); dv = x(4:6); dp = x(7:9); ep = x(10:12); na = x(13:15);
  e = earth(q.pos, q.v);                     % the INS's
  vt = q.v - dv;
  et = earth(q.pos - dp, vt);                % the truth's
  Cpn = rv2m(phi);
  [~, Jr_inv] = rv2J(-phi);
  w = e.wnin - Cpn'*et.wnin - q.Cbp*ep;
  fp = q.Cbp*q.fb;
  dvd = fp - Cpn*fp + Cpn*(q.Cbp*na) - cross(e.wnien, q.v) + cross(et.wnien, vt) ...
        + e.gn - et.gn;
  dpd = [q.v(2)/e.RMh - vt(2)/et.RMh; q.v(1)/e.clRNh - vt(1)/et.clRNh; dv(3)];
  xd = zeros(15, 1);
  xd(1:3) = Jr_inv*w; xd(4:6) = dvd; xd(7:9) = dpd;
end
