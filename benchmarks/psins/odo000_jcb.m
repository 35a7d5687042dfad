function [J, y] = odo000_jcb(f, x, p)
% y = f(x, p) and its Jacobian by central differences (PSINS ekfJcb's interface, for
% ekf(kf, z, 'B') with kf.fx / kf.hx); each state perturbed by 1e-6 in its own unit.
  y = f(x, p);
  n = numel(x); J = zeros(numel(y), n); e = 1e-6;
  for c = 1:n
    d = zeros(n, 1); d(c) = e;
    J(:, c) = (f(x + d, p) - f(x - d, p))/(2*e);
  end
end
