function ckf_000_run(listfile, psins_dir, shim_dir)
% Independent paper-000 CKF (or EKF) run: for every input file named in listfile (one a
% line, written by ckf_000.py), run a PSINS strapdown (insinit/insupdate, two-sample
% coning and sculling) on the raw increments, the model of odo000_fx / odo000_hx, PSINS's
% cubature filter ckf(kf, z, 'B') (ckfCT: third-degree spherical-radial rule) or, where
% the file's filter is 'ekf', PSINS's ekf(kf, z, 'B') on the same maps, and the
% closed-loop feedback once the heading sigma is below the threshold; save the attitude,
% x, P and the bias estimates at every epoch boundary to <input>_out.mat.
% psins_dir: a PSINS work tree (its base/ is added to the path); shim_dir holds a stub
% psinsenvi.m (PSINS generates that file at install time).
  files = psins_runs(listfile, psins_dir, shim_dir);
  global glv
  glv = glvf();
  for f = 1:numel(files)
    t0 = tic;
    d = load(files{f});
    out = run_one(d);
    save('-v7', strrep(files{f}, '.mat', '_out.mat'), '-struct', 'out');
    printf('%s: %d epochs, %.1f s, diverged=%d\n', files{f}, size(out.x, 1) - 1, toc(t0), out.diverged);
    fflush(stdout);
  end
end

function out = run_one(d)
  global glv
  n = double(d.n); K = double(d.K); S = double(d.S); T = double(d.T); dt = double(d.dt);
  wm = d.dtheta; vm = d.dv; dist = d.distance;       % (K*S, 3), (K*S, 3), (K*S, 1)
  ins = insinit([m2att(d.C0); d.v0(:); d.pos0(:)], dt);   % avp0 = [att; vn; pos]
  scale = 1; mount = [0; 0];                         % accumulated odometer scale, mounting
  kf = [];
  kf.xk = zeros(n, 1); kf.Pxk = d.P0;
  kf.Qk = diag(d.qdiag(:))*T; kf.Gammak = eye(n); kf.Rk = d.R;
  use_ekf = isfield(d, 'filter') && strcmp(strtrim(d.filter), 'ekf');
  if use_ekf     % PSINS's ekf: Jacobians of the same maps, by central differences
    kf.fx = @(x, p) odo000_jcb(@odo000_fx, x, p); kf.hx = @(x, p) odo000_jcb(@odo000_hx, x, p);
  else
    kf.fx = @odo000_fx; kf.hx = @odo000_hx;
  end
  out.C = zeros(K+1, 3, 3); out.x = zeros(K+1, n); out.P = zeros(K+1, n, n);
  out.eb = zeros(K+1, 3); out.db = zeros(K+1, 3); out.z = zeros(K, 3);
  out.zhat = zeros(K, 3); out.feedback = zeros(K, 1); out.diverged = 0; out.diverged_k = -1;
  out.C(1, :, :) = a2mat(kf.xk(1:3))*ins.Cnb; out.P(1, :, :) = kf.Pxk;
  for k = 1:K
    C_start = ins.Cnb; disp = zeros(3,1); dS = zeros(3,1); X = zeros(3,1); Z = zeros(3,1);
    sw = zeros(3,1); sf = zeros(3,1); sv = zeros(3,1); sC = zeros(3); spos = zeros(3,1);
    fwd = d.Cmb*[mount(2); 1; -mount(1)];
    steps = 0;
    for j = (k-1)*S + (1:2:S)
      Cp = ins.Cnb; vp = ins.vn; pp = ins.pos;
      ins = insupdate(ins, [wm(j:j+1, :), vm(j:j+1, :)]);
      Cm = 0.5*(Cp + ins.Cnb);  vmid = 0.5*(vp + ins.vn);
      disp = disp + vmid*ins.nts;
      ds = (dist(j) + dist(j+1))*scale;
      dS = dS + Cm*fwd*ds;  X = X + Cm*d.Cmb(:,1)*ds;  Z = Z + Cm*d.Cmb(:,3)*ds;
      sw = sw + ins.eth.wnin(:); sf = sf + Cm*ins.fb*ins.nts; sv = sv + vmid;
      sC = sC + Cm; spos = spos + 0.5*(pp + ins.pos); steps = steps + 1;
    end
    L = (ins.Cnb - C_start)*d.lever(:);
    p = [];
    p.T = T; p.wie = glv.wie; p.win = sw/steps; p.fn = sf/T; p.v = sv/steps;
    p.Cbn = sC/steps; pos = spos/steps; p.lat = pos(1); p.h = pos(3);
    sl2 = sin(p.lat)^2; RN = glv.Re/sqrt(1 - glv.e2*sl2);
    p.RNh = RN + p.h; p.RMh = RN*(1 - glv.e2)/(1 - glv.e2*sl2) + p.h;
    p.dS = dS; p.X = X; p.Z = Z; p.L = L;
    zk = disp - dS - L;
    kf.px = p; kf.py = p;
    if ~out.diverged
      try
        if use_ekf, kf = ekf(kf, zk, 'B'); else, kf = ckf(kf, zk, 'B'); end
        if any(~isfinite(kf.xk)) || any(~isfinite(kf.Pxk(:))), error('nan'); end
        chol(kf.Pxk);
      catch
        out.diverged = 1; out.diverged_k = k;
      end
    end
    out.z(k, :) = zk';
    if isfield(kf, 'ykk_1'), out.zhat(k, :) = kf.ykk_1'; end
    if ~out.diverged && sqrt(kf.Pxk(3,3)) < d.feedback_below
      % closed loop: C_b^n <- C_n'^n(phi^) C_b^n', and the rest; phi's covariance through
      % the reset's Jacobian d phi'/d phi at phi^, C(phi') = C(phi) C(phi^)'.
      xh = kf.xk;
      Cfix = a2mat(xh(1:3));
      [ins.qnb, ins.att, ins.Cnb] = attsyn(m2qua(Cfix*ins.Cnb));
      ins.vn = ins.vn - xh(4:6); ins.pos = ins.pos - xh(7:9);
      ins.eb = ins.eb + xh(10:12); ins.db = ins.db + xh(13:15);
      scale = scale*(1 + xh(16));
      if n >= 18, mount = mount + xh(17:18); end
      J = eye(n); e = 1e-6;
      for c = 1:3
        dd = zeros(3,1); dd(c) = e;
        J(1:3, c) = (m2att(a2mat(xh(1:3) + dd)*Cfix') - m2att(a2mat(xh(1:3) - dd)*Cfix'))/(2*e);
      end
      kf.Pxk = J*kf.Pxk*J'; kf.Pxk = (kf.Pxk + kf.Pxk')/2;
      kf.xk = zeros(n, 1);
      out.feedback(k) = 1;
    end
    out.C(k+1, :, :) = a2mat(kf.xk(1:3))*ins.Cnb;
    out.x(k+1, :) = kf.xk'; out.P(k+1, :, :) = kf.Pxk;
    out.eb(k+1, :) = ins.eb'; out.db(k+1, :) = ins.db';
    if k == 1 && d.check
      out.first = first_update_check(d, p, zk, n, T);
    end
  end
end

function r = first_update_check(d, p, zk, n, T)
% The first epoch from the start's prior: the measurement's predicted mean, covariance and
% cross-covariance from PSINS's cubature transform (ckfCT) against a Monte Carlo
% reference (the same maps, 40000 draws), and the heading update each implies.
  x0 = zeros(n, 1);
  [xp, Pp] = ckfCT(x0, d.P0, @odo000_fx, p);           % cubature time update
  Pp = Pp + diag(d.qdiag(:))*T;
  [zc, Pzc, Pxzc] = ckfCT(xp, Pp, @odo000_hx, p);
  randn('state', 1);
  N = 20000; Lc = chol(d.P0)'; Xs = zeros(n, N); Zs = zeros(3, N);
  for i = 1:N
    Xs(:, i) = odo000_fx(x0 + Lc*randn(n, 1), p);
  end
  Xs = Xs + diag(sqrt(d.qdiag(:)*T))*randn(n, N);
  for i = 1:N
    Zs(:, i) = odo000_hx(Xs(:, i), p);
  end
  xm = mean(Xs, 2); Pm = cov(Xs'); zm = mean(Zs, 2);
  Pzm = cov(Zs'); Pxzm = (Xs - xm)*(Zs - zm)'/(N - 1);
  r.x_cub = xp; r.P_cub = Pp; r.z_cub = zc; r.Pzz_cub = Pzc; r.Pxz_cub = Pxzc;
  r.x_mc = xm; r.P_mc = Pm; r.z_mc = zm; r.Pzz_mc = Pzm; r.Pxz_mc = Pxzm; r.z = zk;
  r.dx_cub = Pxzc/(Pzc + d.R)*(zk - zc);
  r.dx_mc = Pxzm/(Pzm + d.R)*(zk - zm);
  r.dS = p.dS;
end
