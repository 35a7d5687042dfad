function y = gnss_004_fx(x, p)
% One filter epoch (p.T s) of gnss_004_xdot by classical Runge-Kutta 4 with the INS's
% quantities at the epoch's start (p.q0), middle (p.qm) and end (p.q1), as our
% RotationVectorGnssModel.transition does (used as PSINS kf.fx for ukf/ukfUT).
  T = p.T;
  k1 = gnss_004_xdot(x, p.q0);
  k2 = gnss_004_xdot(x + 0.5*T*k1, p.qm);
  k3 = gnss_004_xdot(x + 0.5*T*k2, p.qm);
  k4 = gnss_004_xdot(x + T*k3, p.q1);
  y = x + T/6*(k1 + 2*k2 + 2*k3 + k4);
end
