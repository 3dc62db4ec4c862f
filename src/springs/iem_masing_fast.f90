!> The branch-free loops over many nonlinear springs with which iem_nonlinear_springs evaluates
!> and commits the common move, one that ends on the curve it starts on: with the springs'
!> curves (iem_masing's masing_curve; fast_stresses, fast_commit), or from the top of their
!> stacks (masing_springs, for runs that commit every evaluation): every operation done for
!> every spring and every selection a merge, so that gfortran vectorises them (this file is
!> compiled with -fno-trapping-math in Release builds, and kept apart from its callers:
!> inlined into them, gfortran 12 no longer vectorises the loops). docs/nonlinear.md,
!> section 6a.
module iem_masing_fast
  use iem_kinds, only: wp, ip
  use iem_masing, only: n_masing_constants, k_pos, k_neg, k_branch, k_mirror_pos, k_mirror_neg, &
                        masing_commit, masing_trial
  use iem_masing_simd, only: masing_simd, c_masing_block
  use, intrinsic :: iso_c_binding, only: c_int, c_int32_t
  implicit none
  private
  public :: fast_stresses, fast_commit, masing_springs, n_q, q_half_energy
  public :: n_commit_real, n_commit_int, c_strain, c_stress, c_max_pos, c_max_neg, c_ps, c_e0, &
            c_s0, c_hk, c_lo, c_hi, c_count, c_dir

  !> Columns of a spring's row of constants: the law's (iem_masing's masing_constants, k_pos ..
  !> k_mirror_neg), then half the energy coefficient.
  integer, parameter :: q_half_energy = n_masing_constants + 1, n_q = q_half_energy
  !> Columns of fast_commit's new values: real, then integer.
  integer, parameter :: c_strain = 1, c_stress = 2, c_max_pos = 3, c_max_neg = 4, c_ps = 5, &
                        c_e0 = 6, c_s0 = 7, c_hk = 8, c_lo = 9, c_hi = 10, n_commit_real = 10
  integer, parameter :: c_count = 1, c_dir = 2, n_commit_int = 2
  !> Springs per block of masing_springs (its work arrays stay in L1 cache).
  integer, parameter :: block = 128

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
  !> mv from fast_stresses): the work increments of the fast moves (mv < 2) added, the new
  !> state and curves after the fast moves as masing_commit makes them (a pushed reversal's
  !> point, R_(count) = the committed point before, is stored by the caller), the others' as
  !> they were, into the columns of nr (c_strain .. c_hi) and ni (c_count, c_dir), for the
  !> caller to copy back (stored in place, gfortran 12 makes every unchanged value a masked
  !> store, which is slow).
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

  !> Stresses s of n springs with Emax = 1 (constants p(i, :) from masing_constants) at the
  !> strains e, each reached monotonically from its committed state (e_c .. e_max_neg, stack
  !> depth D), and that state's strain and stress e_was, s_was; with accept, the state moved
  !> to e. Bit for bit masing_trial / masing_commit of each spring: the springs whose move
  !> ends on the curve it starts on (their current one, or the branch a reversal starts) are
  !> evaluated and committed in branch-free loops over a block of springs, the others (a
  !> branch reaches its aim, an overflow retrace its start) take the scalar state machine.
  !> Where iem_masing_simd.c is built with AVX2, its block does both (the state machine of
  !> the commits too), bit for bit; the loops here are then left for the tests.
  pure subroutine masing_springs(n, depth, e, p, accept, e_c, s_c, dir, count, e_rev, s_rev, &
      e_max_pos, e_max_neg, s, e_was, s_was)
    integer, intent(in) :: n, depth
    real(wp), intent(in) :: e(n)
    !> Constants of spring i in p(i, :) (rows past n unused).
    real(wp), intent(in), contiguous :: p(:, :)
    logical, intent(in) :: accept
    real(wp), intent(inout) :: e_c(n), s_c(n)
    integer(ip), intent(inout) :: dir(n), count(n)
    real(wp), intent(inout) :: e_rev(depth, n), s_rev(depth, n), e_max_pos(n), e_max_neg(n)
    real(wp), intent(out) :: s(n), e_was(n), s_was(n)
    ! per spring of a block: the level reached and the direction of its move when fast (0:
    ! not fast, or no move), and what is left to do (0 nothing, 1 store the reversal pushed,
    ! 2 the scalar state machine)
    integer(ip) :: level(block), move(block)
    integer :: todo(block)
    ! with the C block: the springs of the block left to the state machine
    integer(c_int32_t) :: slow(block)
    integer(c_int) :: n_slow
    integer :: b, nb, k, i
    integer(ip) :: lev, m, n0, d0, push, fast, short
    logical :: moved, simd
    real(wp) :: t, e0, s0, aim, d, x, r, y, ek, ec, sc, et, st, eb, pp, pn, pb, mp, mn
    real(wp) :: mirror, half, on_branch
    simd = masing_simd()
    do b = 0, n - 1, block
      nb = min(block, n - b)
      if (simd) then
        ! the loops below in AVX2 vectors (iem_masing_simd.c), bit for bit; then the state
        ! machine for the springs in slow
        call c_masing_block(nb, depth, merge(1, 0, accept), e(b + 1:b + nb), &
                            p(b + 1:b + nb, k_pos), p(b + 1:b + nb, k_neg), &
                            p(b + 1:b + nb, k_branch), p(b + 1:b + nb, k_mirror_pos), &
                            p(b + 1:b + nb, k_mirror_neg), e_c(b + 1:b + nb), &
                            s_c(b + 1:b + nb), dir(b + 1:b + nb), count(b + 1:b + nb), &
                            e_rev(:, b + 1:b + nb), s_rev(:, b + 1:b + nb), &
                            e_max_pos(b + 1:b + nb), e_max_neg(b + 1:b + nb), s(b + 1:b + nb), &
                            e_was(b + 1:b + nb), s_was(b + 1:b + nb), slow, n_slow)
        ! (with accept, every spring is committed: n_slow = 0)
      else
        ! the first pass of masing_walk's loop, without branches: the level reached, the
        ! direction of the move, whether the committed point is pushed as a reversal, and
        ! whether the move ends on the curve it starts on, with the stress there
        do k = 1, nb
          i = b + k
          ! every operand read once, unconditionally (the top of the stack, R_n and R_(n-1),
          ! read as R_1 when there is none, and then not used)
          ek = e(i)
          ec = e_c(i)
          sc = s_c(i)
          n0 = count(i)
          d0 = dir(i)
          et = e_rev(max(n0, 1_ip), i)
          st = s_rev(max(n0, 1_ip), i)
          eb = e_rev(max(n0 - 1_ip, 1_ip), i)
          pp = p(i, k_pos)
          pn = p(i, k_neg)
          pb = p(i, k_branch)
          mp = p(i, k_mirror_pos)
          mn = p(i, k_mirror_neg)
          ! every comparison and every operation is done unconditionally, the conditions are
          ! integers 0 / 1 and merge selects between values, so that the loop has no branch
          m = merge(1_ip, 0_ip, ek > ec) - merge(1_ip, 0_ip, ek < ec)
          push = merge(1_ip, 0_ip, d0 /= 0 .and. m == -d0 .and. n0 < depth)
          lev = n0 + push
          ! start, aim and direction of the branch of that level (masing_walk's level_params):
          ! R_(lev-1) for lev >= 2, the mirror of the start for lev = 1
          e0 = merge(ec, et, push == 1)
          s0 = merge(sc, st, push == 1)
          mirror = -e0*merge(mp, mn, e0 >= 0.0_wp)
          aim = merge(merge(et, eb, push == 1), mirror, lev >= 2)
          d = merge(merge(1.0_wp, -1.0_wp, aim > e0), merge(-1.0_wp, 1.0_wp, e0 > 0.0_wp), &
                    lev >= 2)
          ! on it at e: forward short of its aim, or backward (overflow retrace) short of its
          ! start; an unchanged strain is fast, a NaN is not (masing_commit stores it)
          short = merge(merge(1_ip, 0_ip, d*(ek - aim) < 0.0_wp), &
                        merge(1_ip, 0_ip, d*(ek - e0) > 0.0_wp), real(m, wp) == d)
          fast = max(merge(1_ip, 0_ip, ek == ec), &
                     abs(m)*max(merge(1_ip, 0_ip, lev == 0), short))
          ! the skeleton's and the branches' hyperbolas are one function of (x, strength)
          half = 0.5_wp*(ek - e0)
          x = merge(ek, half, lev == 0)
          r = merge(merge(pp, pn, ek >= 0.0_wp), pb, lev == 0)
          y = x/(1.0_wp + abs(x)/r)
          on_branch = s0 + 2.0_wp*y
          s(i) = merge(sc, merge(y, on_branch, lev == 0), m == 0)
          e_was(i) = ec
          s_was(i) = sc
          level(k) = lev
          move(k) = m*fast
          ! left to do: a pushed reversal to store (accepted), or the state machine
          todo(k) = merge(push*abs(m)*merge(1, 0, accept), 2, fast == 1)
        end do
        if (accept) then
          ! what masing_commit does for a fast move (nothing for an unchanged strain)
          do k = 1, nb
            i = b + k
            moved = move(k) /= 0
            count(i) = merge(level(k), count(i), moved)
            dir(i) = merge(move(k), dir(i), moved)
            e_c(i) = merge(e(i), e_c(i), moved)
            s_c(i) = merge(s(i), s_c(i), moved)
            e_max_pos(i) = merge(max(e_max_pos(i), e(i)), e_max_pos(i), moved)
            e_max_neg(i) = merge(min(e_max_neg(i), e(i)), e_max_neg(i), moved)
          end do
          ! and the reversals it pushed (count(i) is now the level of the new branch)
!GCC$ novector
          do k = 1, nb
            if (todo(k) /= 1) cycle
            i = b + k
            e_rev(count(i), i) = e_was(i)
            s_rev(count(i), i) = s_was(i)
          end do
        end if
        n_slow = 0
        do k = 1, nb
          if (todo(k) /= 2) cycle
          n_slow = n_slow + 1
          slow(n_slow) = k
        end do
      end if
      ! the other springs take the state machine
      do k = 1, n_slow
        i = b + slow(k)
        if (accept) then
          call masing_commit(e(i), 1.0_wp, p(i, k_pos), p(i, k_neg), e_c(i), s_c(i), dir(i), &
                             count(i), e_rev(:, i), s_rev(:, i), e_max_pos(i), e_max_neg(i))
          ! the committed stress is bit for bit the trial stress at the same strain
          s(i) = s_c(i)
        else
          call masing_trial(e(i), 1.0_wp, p(i, k_pos), p(i, k_neg), e_c(i), s_c(i), dir(i), &
                            count(i), e_rev(:, i), s_rev(:, i), s(i), t)
        end if
      end do
    end do
  end subroutine masing_springs
end module iem_masing_fast
