function filters_004_run(listfile, psins_dir, shim_dir)
% Independent paper-004 fine alignments: for every input file named in listfile (one a
% line, written by filters_004.py) and every filter in its `filters` list, run a PSINS
% strapdown (insinit/insupdate, two-sample coning and sculling, biases fed back through
% ins.eb/ins.db) on the raw increments and a PSINS filter, one GNSS update per epoch:
%   stekf        PSINS's state-transformation EKF: kfupdate, Phi = I + etmST(ins) nts per
%                INS step (PSINS's test_SINS_GPS_156_STEKF), H with [(v~ + Lv) x];
%   stekf-native the same without the reset's covariance map (P kept, as PSINS's demo);
%   ekf          kfupdate on PSINS's standard 15-state model, Phi = I + etm(ins) nts;
%   ukf-3n       PSINS's ukf (ukfUT: alpha 1, beta 2, kappa = 3 - n) on the classic
%                large-angle model of gnss_004_fx / gnss_004_hx, one step per epoch;
% then the closed-loop feedback of every epoch: qdelphi(qnb, phi), v -= dv (ST: dv_ST +
% v~ x phi), p -= dp, eb += eps, db += nabla, x = 0 and P <- G P G' with G(phi, phi) =
% rv2J(phi^) (PSINS's left Jacobian) and, ST, G(dv, dv) = rv2m(phi^) (our reset rule).
% Saves the attitude, x, P and the bias estimates at every epoch boundary to
% <input>_<filter>_out.mat.
% psins_dir: a PSINS work tree (its base/ is added to the path); shim_dir holds a stub
% psinsenvi.m (PSINS generates that file at install time).
  files = psins_runs(listfile, psins_dir, shim_dir);
  global glv
  for f = 1:numel(files)
    d = load(files{f});
    glv = glvf(d.Re, d.flattening, d.wie);
    names = strtrim(strsplit(d.filters, ','));
    for i = 1:numel(names)
      t0 = tic;
      out = run_one(d, names{i});
      save('-v7', strrep(files{f}, '.mat', ['_', names{i}, '_out.mat']), '-struct', 'out');
      printf('%s %s: %d epochs, %.1f s, diverged=%d\n', files{f}, names{i}, ...
             size(out.x, 1) - 1, toc(t0), out.diverged);
      fflush(stdout);
    end
  end
end

function out = run_one(d, name)
  n = 15; K = double(d.K); S = double(d.S); T = double(d.T); dt = double(d.dt);
  wm = d.dtheta; vm = d.dv;                          % (K*S, 3) rad, m/s, IMU frame
  ins = insinit([m2att(d.C0); d.v0(:); d.pos0(:)], dt);   % avp0 = [att; vn; pos]
  st = strncmp(name, 'stekf', 5);
  mapP = ~strcmp(name, 'stekf-native');
  ukf3n = strcmp(name, 'ukf-3n');
  kf = [];
  kf.Pxk = d.P0; kf.Rk = d.R; kf.Hk = zeros(6, n); kf.Gammak = eye(n);
  if ukf3n
    kf.xk = zeros(n, 1); kf.Qk = diag(d.qdiag(:))*T;
    kf.alpha = 1; kf.beta = 2; kf.kappa = 3 - n;
    kf.fx = @gnss_004_fx; kf.hx = @gnss_004_hx;
  else
    kf.Qk = diag(d.qdiag(:))*2*dt;
    kf = kfinit0(kf, 2*dt);
  end
  out.C = zeros(K+1, 3, 3); out.x = zeros(K+1, n); out.P = zeros(K+1, n, n);
  out.eb = zeros(K+1, 3); out.db = zeros(K+1, 3);
  out.diverged = 0; out.diverged_k = -1;
  out.C(1, :, :) = ins.Cnb; out.P(1, :, :) = kf.Pxk;
  mid = S/2;
  for k = 1:K
    j0 = (k-1)*S;
    q0 = quantities(ins, (vm(j0+1, :)' - ins.db*dt)/dt);
    for j = j0 + (1:2:S)
      ins = insupdate(ins, [wm(j:j+1, :), vm(j:j+1, :)]);
      if j + 1 == j0 + mid
        qm = quantities(ins, (0.5*(vm(j+1, :) + vm(j+2, :))' - ins.db*dt)/dt);
      end
      if ~ukf3n && ~out.diverged
        if st, Ft = etmST(ins); else, Ft = etm(ins); end
        kf.Phikk_1 = eye(n) + Ft*ins.nts;
        kf = kfupdate(kf);
      end
    end
    q1 = quantities(ins, (vm(j0+S, :)' - ins.db*dt)/dt);
    % the measurement (our RotationVectorGnssModel.observation)
    C = ins.Cnb; l = d.lever(k+1, :)'; wbs = d.omega_bs(k+1, :)';
    r = (wm(j0+S-1:j0+S, :)' - ins.eb*dt)/dt;          % the last two intervals' rates
    eth = earth(ins.pos, ins.vn);
    wnb = 1.5*r(:, 2) - 0.5*r(:, 1) - wbs - C'*eth.wnin; % at the fix, the hull's rate
    Lp = C*l; Lv = C*cross(wnb, l);
    D = [0, eth.clRNh, 0; eth.RMh, 0, 0; 0, 0, 1];
    dpos = ins.pos - [d.gps_lat(k+1); d.gps_lon(k+1); d.gps_h(k+1)];
    zk = [ins.vn + Lv - d.gps_v(k+1, :)'; D*dpos + Lp];
    if ~out.diverged
      try
        if ukf3n
          kf.px = struct('T', T, 'q0', q0, 'qm', qm, 'q1', q1);
          kf.py = struct('Lv', Lv, 'Lp', Lp, 'D', D);
          kf = ukf(kf, zk, 'B');
        else
          H = zeros(6, n);
          H(1:3, 1:3) = askew(Lv + st*ins.vn); H(1:3, 4:6) = eye(3);
          H(4:6, 1:3) = askew(Lp); H(4:6, 7:9) = D;
          kf.Hk = H;
          kf = kfupdate(kf, zk, 'M');
        end
        if any(~isfinite(kf.xk)) || any(~isfinite(kf.Pxk(:))), error('nan'); end
        chol(kf.Pxk);
      catch
        out.diverged = 1; out.diverged_k = k;
      end
    end
    if ~out.diverged
      xh = kf.xk;
      [ins.qnb, ins.att, ins.Cnb] = attsyn(qdelphi(ins.qnb, xh(1:3)));
      if st, dv = xh(4:6) + askew(ins.vn)*xh(1:3); else, dv = xh(4:6); end
      ins.vn = ins.vn - dv; ins.pos = ins.pos - xh(7:9);
      ins.eb = ins.eb + xh(10:12); ins.db = ins.db + xh(13:15);
      if mapP
        G = eye(n); G(1:3, 1:3) = rv2J(xh(1:3));
        if st, G(4:6, 4:6) = rv2m(xh(1:3)); end
        kf.Pxk = G*kf.Pxk*G'; kf.Pxk = (kf.Pxk + kf.Pxk')/2;
      end
      kf.xk = zeros(n, 1);
    end
    out.C(k+1, :, :) = rv2m(kf.xk(1:3))*ins.Cnb;
    out.x(k+1, :) = kf.xk'; out.P(k+1, :, :) = kf.Pxk;
    out.eb(k+1, :) = ins.eb'; out.db(k+1, :) = ins.db';
  end
end

function q = quantities(ins, fb)
% The INS's attitude, velocity and position now and the specific force fb (IMU frame).
  q = struct('Cbp', ins.Cnb, 'fb', fb, 'v', ins.vn, 'pos', ins.pos);
end
