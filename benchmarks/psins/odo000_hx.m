function z = odo000_hx(x, p)
% Position-increment measurement of paper 000 (ALGORITHMS 4.6-4.7), exact in the Euler
% angles, the odometer scale and the mounting:
%   z = sum v~ Ts - dS - L  (INS displacement less the odometer's and the lever arm's,
%       all resolved with the INS attitude C_b^n')
%     = T dv_bar + C [(1 + dK_D)(dS + psi_m X - theta_m Z) + L] - dS - L,
% C = C_n'^n(phi); dS, X, Z: the odometer's distance resolved along the odometer's
% forward, right and up axes; L the lever arm's displacement; dv_bar the epoch's mean
% velocity error, dv_k - (T/2) dv_dot(x_k).
  C = a2mat(x(1:3));
  xd = odo000_xdot(x, p);
  dvbar = x(4:6) - 0.5*p.T*xd(4:6);
  s = p.dS;
  if numel(x) >= 18
    s = s + x(18)*p.X - x(17)*p.Z;
  end
  z = p.T*dvbar + C*((1 + x(16))*s + p.L) - p.dS - p.L;
end
