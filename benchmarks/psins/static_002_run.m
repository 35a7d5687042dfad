function static_002_run(listfile, psins_dir, shim_dir)
% Independent paper-002 alignment on a static base: for every input file named in
% listfile (one a line, written by static_002.py), PSINS's large-misalignment EKF
% (alignvn_ekf: 5 states phi, dvE, dvN; Jacob5) and its state-transformation EKF
% (alignvn_stekf: 12 states phi, dv, eb, db) on the episode's raw increments, from the
% same INS start, with the file's P0 (phi0, eb, db), noise densities (web, wdb) and
% velocity sigma (wvn); saves their attitude and covariance diagonal at every PSINS step
% (two IMU samples) to <input>_out.mat.
  files = psins_runs(listfile, psins_dir, shim_dir);
  global glv
  glv = glvf();
  for f = 1:numel(files)
    t0 = tic;
    d = load(files{f});
    imuerr = struct('eb', d.eb(:), 'db', d.db(:), 'web', d.web(:), 'wdb', d.wdb(:));
    imu = [d.dtheta, d.dv, d.t(:)];
    qnb = m2qua(d.C0);
    [~, att_ekf, xp_ekf] = alignvn_ekf(imu, qnb, d.pos(:), d.phi0(:), imuerr, d.wvn(:), 0);
    [~, att_st, xp_st] = alignvn_stekf(imu, qnb, d.pos(:), d.phi0(:), imuerr, d.wvn(:), 0);
    out = struct('att_ekf', att_ekf, 'xp_ekf', xp_ekf, 'att_stekf', att_st, 'xp_stekf', xp_st);
    save('-v7', strrep(files{f}, '.mat', '_out.mat'), '-struct', 'out');
    printf('%s: %.1f s\n', files{f}, toc(t0));
    fflush(stdout);
  end
end
