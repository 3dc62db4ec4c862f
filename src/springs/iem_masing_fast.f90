!> The branch-free loops over many nonlinear springs with which iem_nonlinear_springs evaluates
!> and commits the common move, one that ends on the curve it starts on (iem_masing's
!> masing_curve): every operation done for every spring and every selection a merge, so that
!> gfortran vectorises them (this file is compiled with -fno-trapping-math in Release builds,
!> and kept apart from its callers: inlined into them, gfortran 12 no longer vectorises the
!> loops). docs/nonlinear.md, section 6a.
module iem_masing_fast
  use iem_kinds, only: wp, ip
  use iem_masing, only: n_masing_constants, k_pos, k_neg, k_branch, k_mirror_pos, k_mirror_neg
  implicit none
  private
  public :: fast_stresses, fast_commit, n_q, q_half_energy
  public :: n_commit_real, n_commit_int, c_strain, c_stress, c_max_pos, c_max_neg, c_ps, c_e0, &
            c_s0, c_hk, c_lo, c_hi, c_count, c_dir

  !> Columns of a spring's row of constants: the law's (iem_masing's masing_constants, k_pos ..
  !> k_mirror_neg), then half the energy coefficient.
  integer, parameter :: q_half_energy = n_masing_constants + 1, n_q = q_half_energy
  !> Columns of fast_commit's new values: real, then integer.
  integer, parameter :: c_strain = 1, c_stress = 2, c_max_pos = 3, c_max_neg = 4, c_ps = 5, &
                        c_e0 = 6, c_s0 = 7, c_hk = 8, c_lo = 9, c_hi = 10, n_commit_real = 10
  integer, parameter :: c_count = 1, c_dir = 2, n_commit_int = 2

contains

  !> The branch-free loop of iem_nonlinear_springs' stress over n springs (constants p(off +
  !> k, :), p of leading dimension ldp) at strains e, with their committed strain e_c and stress s_c
  !> and their curves: the stress s on the curve each move starts on, and the kind of move:
  !> mv = 0 when it ends on the curve it continues (or does not move), 1 when it ends on the
  !> branch it starts by a push, 2 otherwise (s is then not its stress).
  pure subroutine fast_stresses(n, e, p, ldp, off, e_c, s_c, ps, e0, s0, hk, lo, hi, s, mv)
    !> Spring k's constants are row off + k of p.
    integer, intent(in) :: n, ldp, off
    real(wp), intent(in) :: e(n), p(ldp, n_q), e_c(n), s_c(n), ps(n), e0(n), s0(n), hk(n)
    real(wp), intent(in) :: lo(n), hi(n)
    real(wp), intent(out) :: s(n), mv(n)
    integer :: k
    real(wp) :: ek, ec, sc, up, dn, mr, push, skel, e0k, s0k, x, r, y, fast
    real(wp) :: psk, hkk, lok, hik, pp, pn, pb
    ! every operation done for every spring, every condition a 0/1 value and every selection
    ! a merge of values read before (a merge of array elements would be a masked read), so
    ! that the loop has no branch and vectorises
    do k = 1, n
      ek = e(k)
      ec = e_c(k)
      sc = s_c(k)
      psk = ps(k)
      e0k = e0(k)
      s0k = s0(k)
      hkk = hk(k)
      lok = lo(k)
      hik = hi(k)
      pp = p(off + k, k_pos)
      pn = p(off + k, k_neg)
      pb = p(off + k, k_branch)
      up = merge(1.0_wp, 0.0_wp, ek > ec)
      dn = merge(1.0_wp, 0.0_wp, ek < ec)
      mr = up - dn
      ! a push starts a branch at the committed point, else the move continues the curve
      push = abs(mr)*merge(1.0_wp, 0.0_wp, mr == psk)
      e0k = merge(ec, e0k, push > 0.0_wp)
      s0k = merge(sc, s0k, push > 0.0_wp)
      skel = (1.0_wp - push)*merge(1.0_wp, 0.0_wp, hkk == 1.0_wp)
      ! the skeleton's and the branches' hyperbolas are one function of (x, strength)
      x = merge(ek, 0.5_wp*(ek - e0k), skel > 0.0_wp)
      r = merge(merge(pp, pn, ek >= 0.0_wp), pb, skel > 0.0_wp)
      y = x/(1.0_wp + abs(x)/r)
      s(k) = merge(sc, merge(y, s0k + 2.0_wp*y, skel > 0.0_wp), ek == ec)
      ! fast when it ends short of the end of its curve, or does not move
      fast = max(up*merge(1.0_wp, 0.0_wp, ek < hik), dn*merge(1.0_wp, 0.0_wp, ek > lok), &
                 merge(1.0_wp, 0.0_wp, ek == ec))
      mv(k) = merge(push, 2.0_wp, fast > 0.0_wp)
    end do
  end subroutine fast_stresses

  !> The branch-free loop of iem_nonlinear_springs' commit over n springs (as fast_stresses;
  !> mv from fast_stresses): the work increments of the fast moves (mv < 2) added, the new state and curves after
  !> the fast moves (mv < 2) as masing_commit makes them (a pushed reversal's point, R_(count)
  !> = the committed point before, is stored by the caller), the others' as they were, into
  !> the columns of nr (c_strain .. c_hi) and ni (c_count, c_dir), for the caller to copy
  !> back (stored in place, gfortran 12 makes every unchanged value a masked store, which is
  !> slow).
  pure subroutine fast_commit(n, room, e, p, ldp, off, s, mv, e_c, s_c, dir, count, e_max_pos, &
                              e_max_neg, ps, e0, s0, hk, lo, hi, work, ldr, nr, ni)
    !> Spring k's constants are row off + k of p; nr and ni have leading dimension ldr >= n.
    integer, intent(in) :: n, ldp, off, ldr
    !> The room left on each spring's stack, less one: depth - count - 1.
    real(wp), intent(in) :: room(n)
    real(wp), intent(in) :: e(n), p(ldp, n_q), s(n), mv(n)
    real(wp), intent(in) :: e_c(n), s_c(n), e_max_pos(n), e_max_neg(n)
    integer(ip), intent(in) :: dir(n), count(n)
    real(wp), intent(in) :: ps(n), e0(n), s0(n), hk(n), lo(n), hi(n)
    real(wp), intent(inout) :: work(n)
    real(wp), intent(out) :: nr(ldr, n_commit_real)
    integer(ip), intent(out) :: ni(ldr, n_commit_int)
    integer :: k
    integer(ip) :: dk, nk
    real(wp) :: ek, ec, sc, sk, mr, moved, push, branch, mp, mn, aim, d, b, pushed_end
    real(wp) :: pm, ps_new, hi_new, lo_new, hik, lok, e0k, s0k, hkk, psk, emp, emn, wk, dw
    ! as fast_stresses: every array element read into a variable first, one merge a value
    ! of one 0/1 condition (nested ones stop gfortran 12 vectorising), and two loops: the
    ! curves, then the state (one loop is too much for it)
    do k = 1, n
      ek = e(k)
      ec = e_c(k)
      sc = s_c(k)
      psk = ps(k)
      e0k = e0(k)
      s0k = s0(k)
      hkk = hk(k)
      lok = lo(k)
      hik = hi(k)
      mp = p(off + k, k_mirror_pos)
      mn = p(off + k, k_mirror_neg)
      mr = merge(1.0_wp, 0.0_wp, ek > ec) - merge(1.0_wp, 0.0_wp, ek < ec)
      ! a fast move (a NaN strain is not one)
      moved = merge(1.0_wp, 0.0_wp, ek /= ec)*merge(1.0_wp, 0.0_wp, mv(k) < 2.0_wp)
      push = merge(1.0_wp, 0.0_wp, mv(k) == 1.0_wp)
      pm = push*moved
      branch = merge(1.0_wp, 0.0_wp, hkk == 0.5_wp)
      ! without a push the curve stays and the spring goes the way mr: the branch a later
      ! push would start from the new committed point ek ends at its aim (R_n above the
      ! skeleton, the mirror point on it) when that lies against the move, else at ek
      aim = merge(e0k, -ek*merge(mp, mn, ek >= 0.0_wp), branch > 0.0_wp)
      d = merge(merge(1.0_wp, -1.0_wp, aim > ek), merge(-1.0_wp, 1.0_wp, ek > 0.0_wp), &
                branch > 0.0_wp)
      b = merge(aim, ek, -mr == d)
      ! with a push the new branch starts at ec and goes the way mr up to the aim of that
      ! branch (R_n, or the mirror of ec on the skeleton); back, it ends at ec
      pushed_end = merge(e0k, -ec*merge(mp, mn, ec >= 0.0_wp), branch > 0.0_wp)
      ps_new = merge(-mr, 0.0_wp, push <= room(k))
      ! the side of the move keeps its end (no push) or takes the pushed branch's; the other
      ! side takes the end of the branch a push would start (no change when none can: a full
      ! stack retraced), or ec
      hi_new = merge(merge(pushed_end, hik, push > 0.0_wp), &
                     merge(ec, merge(b, hik, ps_new /= 0.0_wp), push > 0.0_wp), mr > 0.0_wp)
      lo_new = merge(merge(pushed_end, lok, push > 0.0_wp), &
                     merge(ec, merge(b, lok, ps_new /= 0.0_wp), push > 0.0_wp), mr < 0.0_wp)
      nr(k, c_hi) = merge(hi_new, hik, moved > 0.0_wp)
      nr(k, c_lo) = merge(lo_new, lok, moved > 0.0_wp)
      nr(k, c_e0) = merge(ec, e0k, pm > 0.0_wp)
      nr(k, c_s0) = merge(sc, s0k, pm > 0.0_wp)
      nr(k, c_hk) = merge(0.5_wp, hkk, pm > 0.0_wp)
      nr(k, c_ps) = merge(ps_new, psk, moved > 0.0_wp)
    end do
    do k = 1, n
      ek = e(k)
      sk = s(k)
      ec = e_c(k)
      sc = s_c(k)
      dk = dir(k)
      nk = count(k)
      emp = e_max_pos(k)
      emn = e_max_neg(k)
      wk = work(k)
      mr = merge(1.0_wp, 0.0_wp, ek > ec) - merge(1.0_wp, 0.0_wp, ek < ec)
      moved = merge(1.0_wp, 0.0_wp, ek /= ec)*merge(1.0_wp, 0.0_wp, mv(k) < 2.0_wp)
      push = merge(1.0_wp, 0.0_wp, mv(k) == 1.0_wp)
      ! the work increment of a fast move (trapezoidal from the committed state; the others'
      ! the caller adds)
      dw = p(off + k, q_half_energy)*(sc + sk)*(ek - ec)
      work(k) = wk + merge(dw, 0.0_wp, mv(k) < 2.0_wp)
      nr(k, c_strain) = merge(ek, ec, moved > 0.0_wp)
      nr(k, c_stress) = merge(sk, sc, moved > 0.0_wp)
      nr(k, c_max_pos) = merge(max(emp, ek), emp, moved > 0.0_wp)
      nr(k, c_max_neg) = merge(min(emn, ek), emn, moved > 0.0_wp)
      ni(k, c_count) = merge(nk + int(push, ip), nk, moved > 0.0_wp)
      ni(k, c_dir) = merge(int(mr, ip), dk, moved > 0.0_wp)
    end do
  end subroutine fast_commit
end module iem_masing_fast
