function y = odo000_fx(x, p)
% One filter step (p.T s) of odo000_xdot by classical Runge-Kutta 4 with the epoch's INS
% quantities held constant (used as PSINS kf.fx for ckf/ckfCT).
  T = p.T;
  k1 = odo000_xdot(x, p);
  k2 = odo000_xdot(x + 0.5*T*k1, p);
  k3 = odo000_xdot(x + 0.5*T*k2, p);
  k4 = odo000_xdot(x + T*k3, p);
  y = x + T/6*(k1 + 2*k2 + 2*k3 + k4);
end
