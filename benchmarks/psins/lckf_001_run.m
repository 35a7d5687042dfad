function lckf_001_run(listfile, psins_dir, shim_dir)
% Independent paper-001 classic loosely coupled GPS/INS run: for every input file named in
% listfile (one a line, written by lckf_001.py), a PSINS strapdown (insinit/insupdate,
% two-sample coning and sculling, 2 IMU samples a step) and PSINS's classic 15-state KF
% (psinstypedef(156): kfinit, etm via kffk, kfhk, kfupdate, kffeedback) with lckf's
% tuning; the GPS position and velocity fixes at the antenna through PSINS's inslever;
% closed-loop feedback of all 15 states after every fix. Saves the navigation solution,
% xk and Pxk at every epoch boundary to <input>_out.mat.
% States (PSINS): [phi (3, ENU, rad; C~ = (I - [phi x]) C, as lckf's phi^e), dvn (3, ENU,
% m/s), dpos (lat rad, lon rad, h m), eb (3, body, rad/s), db (3, body, m/s^2)]; the
% input P0 is already mapped to these states (lckf_001.py, psins_map).
% Diagnostics (the input's rate, discretisation, gravity: 'psins' or 'lckf', from
% lckf_001.py --as-lckf): the lever-arm body rate extrapolated to the fix, one time update
% an epoch as lckf does it, and PSINS's gravity fixed at ours (glv.gfix).
% psins_dir: a PSINS work tree (its base/ is added to the path); shim_dir holds a stub
% psinsenvi.m (PSINS generates that file at install time).
  files = psins_runs(listfile, psins_dir, shim_dir);
  global glv
  for f = 1:numel(files)
    t0 = tic;
    d = load(files{f});
    glv = glvf(d.Re, d.flattening, d.wie);   % the project's WGS-84 (PSINS's f: 1/298.257)
    if strcmp(d.gravity, 'lckf'), glv.gfix = d.g_fix; end  % ours at the start, fixed
    out = run_one(d);
    save('-v7', strrep(files{f}, '.mat', '_out.mat'), '-struct', 'out');
    printf('%s: %d epochs, %d fixes, %.1f s\n', files{f}, size(out.pos, 1) - 1, ...
           sum(out.updated), toc(t0));
    fflush(stdout);
  end
end

function out = run_one(d)
  K = double(d.K); S = double(d.S); dt = double(d.dt); lever = d.lever(:);
  if mod(S, 2), error('S = %d IMU samples an epoch: need an even number', S); end
  wm = d.dtheta; vm = d.dv;                            % (K*S, 3) rad, m/s
  ins = insinit([m2att(d.C0); d.v0(:); d.pos0(:)], dt);  % [att; v^n ENU; lat, lon, h]
  ins.nts = 2*dt;
  psinstypedef(156);                                   % 15 states, z = [dvn; dpos]
  imuerr = [];
  imuerr.web = d.gyro_noise*ones(3, 1); imuerr.wdb = d.accel_noise*ones(3, 1);
  imuerr.eb = d.gyro_bias_sigma*ones(3, 1); imuerr.db = d.accel_bias_sigma*ones(3, 1);
  davp = sqrt(diag(d.P0(1:9, 1:9)));                   % replaced by the full P0 below
  kf = kfinit(ins, davp, imuerr, ones(6, 1));          % Qt = diag([web; wdb; 0])^2
  kf.Pxk = d.P0;                                       % lckf's P0, mapped (correlated)
  kf.Pmax = (diag(kf.Pxk) + 1)*1e10;
  n = kf.n;
  out.pos = zeros(K+1, 3); out.vn = zeros(K+1, 3); out.C = zeros(K+1, 3, 3);
  out.eb = zeros(K+1, 3); out.db = zeros(K+1, 3);
  out.x = zeros(K+1, n); out.P = zeros(K+1, n, n); out.z = nan(K, 6);
  out.updated = zeros(K, 1);
  out = store(out, 1, ins, kf);
  one_step = strcmp(d.discretisation, 'lckf');
  for k = 1:K
    js = (k-1)*S + (1:2:S);
    for j = js
      ins = insupdate(ins, [wm(j:j+1, :), vm(j:j+1, :)]);
      if one_step
        if j == js(numel(js)/2), Ft = etm(ins); Cmid = ins.Cnb; end
      else
        kf.Phikk_1 = kffk(ins);                        % I + etm(ins)*nts
        kf = kfupdate(kf);                             % time update, Qk = Qt*nts
      end
    end
    if one_step
      % lckf's own: one step per epoch from mid-epoch, f^n from the epoch's mean force,
      % Phi = I + F T + (F T)^2 / 2, Q = T / 2 (Phi Qc Phi' + Qc).
      T = double(d.T); idx = (k-1)*S + (1:S);
      fn = Cmid*(sum(vm(idx, :), 1)' - ins.db*S*dt)/T;
      Ft(4:6, 1:3) = askew(fn);
      FT = Ft*T; kf.Phikk_1 = eye(n) + FT + FT*FT/2;
      kf.Qk = T/2*(kf.Phikk_1*kf.Qt*kf.Phikk_1' + kf.Qt);
      kf = kfupdate(kf);
    end
    gv = d.gps_vn(k+1, :)'; gp = d.gps_pos(k+1, :)';
    if all(isfinite([gv; gp]))
      if strcmp(d.rate, 'lckf')
        % lckf's body rate at the fix: the last two samples' rates extrapolated to the
        % boundary (1.5 r_S - 0.5 r_S-1), PSINS's eb removed, less the earth rate.
        j = k*S;
        r = (wm(j-1:j, :)' - ins.eb*dt)/dt;
        ins.web = 1.5*r(:, 2) - 0.5*r(:, 1) - ins.Cnb'*ins.eth.wnie;
      end
      ins = inslever(ins, lever);                      % vnL, posL at the antenna
      zk = [ins.vnL - gv; ins.posL - gp];
      kf.Hk = kfhk(ins) + lever_columns(ins, lever);
      kf.Rk = diag([d.gps_velocity_sigma*ones(3, 1); d.gps_position_sigma_h/ins.eth.RMh; ...
                    d.gps_position_sigma_h/ins.eth.clRNh; d.gps_position_sigma_v])^2;
      kf = kfupdate(kf, zk, 'M');
      out.z(k, :) = zk'; out.updated(k) = 1;
    end
    [kf, ins] = kffeedback(kf, ins, d.T_fb, d.fbstr);  % coef 1: all of xk, xk <- 0
    out = store(out, k+1, ins, kf);
  end
end

function H = lever_columns(ins, lever)
% The lever arm's rows that PSINS's kfhk(156) leaves out (its 186/196 types carry the lever
% arm as a state instead), from inslever's own terms: vnL = vn + Cnb (web x l), posL =
% pos + Mpv Cnb l, with C~ = (I - [phi x]) C and web~ = web + eb give
% d vnL = dvn + [(Cnb (web x l)) x] phi - Cnb [l x] eb, d posL = dpos + Mpv [(Cnb l) x] phi.
  H = zeros(6, 15);
  H(1:3, 1:3) = askew(ins.CW*lever);
  H(1:3, 10:12) = -ins.Cnb*askew(lever);
  H(4:6, 1:3) = ins.Mpv*askew(ins.Cnb*lever);
end

function out = store(out, i, ins, kf)
  out.pos(i, :) = ins.pos'; out.vn(i, :) = ins.vn'; out.C(i, :, :) = ins.Cnb;
  out.eb(i, :) = ins.eb'; out.db(i, :) = ins.db';
  out.x(i, :) = kf.xk'; out.P(i, :, :) = kf.Pxk;
end
