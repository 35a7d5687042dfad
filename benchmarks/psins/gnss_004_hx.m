function z = gnss_004_hx(x, p)
% GNSS velocity and position measurement of paper 004 on the classic state (the INS at
% the antenna minus the fix, ENU m/s and m; RotationVectorGnssModel.observation):
%   z = [dv + (I - C_p^n) Lv;  D dp + (I - C_p^n) Lp],   C_p^n = rv2m(phi),
% Lv = C_b^p (w_nh x l), Lp = C_b^p l the lever arm's velocity and offset as the INS
% resolves them (l: IMU to antenna, IMU frame, turning with the indexer), D the metres
% of (dL, dlambda, dh) along E, N, U.
  C = rv2m(x(1:3));
  z = [x(4:6) + p.Lv - C*p.Lv; p.D*x(7:9) + p.Lp - C*p.Lp];
end
