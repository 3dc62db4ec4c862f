!> The branch-free part of iem_masing_fast's masing_springs written with AVX2 vectors
!> (iem_masing_simd.c): a block of springs' stresses and, with accept, their commit (the state
!> machine's too), bit for bit as masing_springs' loops and iem_masing's masing_commit form
!> them; and the commit of springs that keep their curves, in place, bit for bit as
!> fast_stresses and fast_commit; the Fortran loops run where the C file is built without
!> AVX2 (docs/nonlinear.md, section 6a).
module iem_masing_simd
  use, intrinsic :: iso_c_binding, only: c_int, c_double, c_int32_t
  implicit none
  private
  public :: masing_simd, use_masing_simd, c_masing_block, c_curve_commit, c_curve_stress

  !> Whether the block of iem_masing_simd.c is used when built (tests clear it to compare it
  !> with the Fortran loops).
  logical :: use_masing_simd = .true.

  interface
    !> 1 when iem_masing_simd.c's block is built (AVX2), else 0.
    pure integer(c_int) function c_simd() bind(c, name='iem_masing_block_simd')
      import :: c_int
    end function c_simd
    !> masing_springs over n springs (constants of spring i in pp(i) .. mn(i)): with accept
    !> /= 0 every spring committed (n_slow = 0), else the springs left to masing_trial in
    !> slow(1:n_slow); where built.
    pure subroutine c_masing_block(n, depth, accept, e, pp, pn, pb, mp, mn, e_c, s_c, dir, &
                                   count, e_rev, s_rev, e_max_pos, e_max_neg, s, e_was, s_was, &
                                   slow, n_slow) bind(c, name='iem_masing_block')
      import :: c_int, c_double, c_int32_t
      integer(c_int), value :: n, depth, accept
      real(c_double), intent(in) :: e(*), pp(*), pn(*), pb(*), mp(*), mn(*)
      real(c_double), intent(inout) :: e_c(*), s_c(*), e_max_pos(*), e_max_neg(*)
      real(c_double), intent(inout) :: e_rev(*), s_rev(*)
      integer(c_int32_t), intent(inout) :: dir(*), count(*)
      real(c_double), intent(inout) :: s(*), e_was(*), s_was(*)
      integer(c_int32_t), intent(inout) :: slow(*)
      integer(c_int), intent(out) :: n_slow
    end subroutine c_masing_block
    !> The commit of n springs that keep their curves (iem_nonlinear_springs' commit), in
    !> place, bit for bit fast_stresses and fast_commit with the pushed reversals stored, and
    !> masing_commit with the work increment for the others, listed in slow(1:n_slow) (their
    !> curves to be made again); where built.
    pure subroutine c_curve_commit(n, depth, e, pp, pn, pb, mp, mn, hq, e_c, s_c, dir, count, &
                                   e_rev, s_rev, e_max_pos, e_max_neg, ps, e0, s0, hk, lo, hi, &
                                   work, s, slow, n_slow) bind(c, name='iem_curve_commit')
      import :: c_int, c_double, c_int32_t
      integer(c_int), value :: n, depth
      real(c_double), intent(in) :: e(*), pp(*), pn(*), pb(*), mp(*), mn(*), hq(*)
      real(c_double), intent(inout) :: e_c(*), s_c(*), e_max_pos(*), e_max_neg(*)
      real(c_double), intent(inout) :: e_rev(*), s_rev(*)
      integer(c_int32_t), intent(inout) :: dir(*), count(*)
      real(c_double), intent(inout) :: ps(*), e0(*), s0(*), hk(*), lo(*), hi(*), work(*)
      real(c_double), intent(out) :: s(*)
      integer(c_int32_t), intent(out) :: slow(*)
      integer(c_int), intent(out) :: n_slow
    end subroutine c_curve_commit
    !> The stresses of n springs that keep their curves (iem_nonlinear_springs' stress), bit
    !> for bit fast_stresses with the kinds of the moves mv, and masing_trial for those of
    !> kind 2, listed in slow(1:n_slow); where built.
    pure subroutine c_curve_stress(n, depth, e, pp, pn, pb, mp, mn, e_c, s_c, dir, count, &
                                   e_rev, s_rev, ps, e0, s0, hk, lo, hi, s, mv, slow, n_slow) &
        bind(c, name='iem_curve_stress')
      import :: c_int, c_double, c_int32_t
      integer(c_int), value :: n, depth
      real(c_double), intent(in) :: e(*), pp(*), pn(*), pb(*), mp(*), mn(*), e_c(*), s_c(*)
      integer(c_int32_t), intent(in) :: dir(*), count(*)
      real(c_double), intent(in) :: e_rev(*), s_rev(*), ps(*), e0(*), s0(*), hk(*), lo(*)
      real(c_double), intent(in) :: hi(*)
      real(c_double), intent(out) :: s(*), mv(*)
      integer(c_int32_t), intent(out) :: slow(*)
      integer(c_int), intent(out) :: n_slow
    end subroutine c_curve_stress
  end interface

contains

  !> Whether the block of iem_masing_simd.c runs (built with AVX2, and use_masing_simd).
  pure logical function masing_simd()
    masing_simd = use_masing_simd .and. c_simd() == 1
  end function masing_simd
end module iem_masing_simd
