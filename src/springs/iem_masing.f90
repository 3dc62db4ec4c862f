!> Nonlinear spring law: hyperbolic skeleton and Masing hysteresis with the extended rules
!> (model.md section 4). The exact state machine is in docs/nonlinear.md.
!>
!> A spring's history is a stack of reversal points R_1..R_n. Level 0 is the skeleton;
!> level k >= 1 is the branch that starts at R_k. Every branch is the doubled hyperbola
!> s = s_k + 2 h((e - e_k)/2), h(x) = Emax x/(1 + Emax |x|/sb), sb = (smax_pos + smax_neg)/2,
!> so it leaves its reversal with the tangent Emax. With equal strengths sb = smax and this is
!> Masing's rule with f the skeleton. Branch k aims at R_(k-1) (k >= 2), which it passes
!> through exactly, or at the mirror of R_1 on the skeleton of the other sign (k = 1), which it
!> touches tangentially; past its aim strain it has rejoined the curve it interrupted, which is
!> level k-2 (the skeleton for k <= 2).
module iem_masing
  use iem_kinds, only: wp, ip
  implicit none
  private
  public :: masing_default_depth, masing_state_t
  public :: skeleton_stress, skeleton_tangent, hyperbola_stress, hyperbola_tangent
  public :: masing_branch_strength, masing_mirror_strain
  public :: masing_trial, masing_commit, masing_stress_all, masing_commit_all
  public :: masing_constants, masing_curve, n_masing_constants
  public :: k_pos, k_neg, k_branch, k_mirror_pos, k_mirror_neg

  !> Default number of reversal points kept per spring (nested loops remembered: depth/2).
  integer(ip), parameter :: masing_default_depth = 8

  !> Number of constants of a spring's law (masing_constants): the two strengths, the branch
  !> strength and the two mirror factors, at these indices.
  integer, parameter :: n_masing_constants = 5
  integer, parameter :: k_pos = 1, k_neg = 2, k_branch = 3, k_mirror_pos = 4, k_mirror_neg = 5

  !> History of many nonlinear springs, struct of arrays; spring i's stack is column i.
  type :: masing_state_t
    !> Number of springs and stack depth D.
    integer(ip) :: n = 0, depth = 0
    !> Committed strain and stress of each spring.
    real(wp), allocatable :: strain(:), stress(:)
    !> Direction of the last strain change: +1, -1, or 0 before the first change.
    integer(ip), allocatable :: dir(:)
    !> Number of reversal points on each spring's stack (0: on the skeleton).
    integer(ip), allocatable :: count(:)
    !> Reversal points (strain, stress), (depth, n): entry k of column i is R_k of spring i.
    real(wp), allocatable :: e_rev(:, :), s_rev(:, :)
    !> Largest strain reached in tension (>= 0) and in compression (<= 0).
    real(wp), allocatable :: e_max_pos(:), e_max_neg(:)
  contains
    procedure :: init => masing_state_init
    procedure :: free => masing_state_free
    procedure :: trial => masing_state_trial
    procedure :: commit => masing_state_commit
  end type masing_state_t

contains

  !> Hyperbola Emax x/(1 + Emax |x|/smax) with one strength for both signs.
  pure elemental function hyperbola_stress(x, emax, smax) result(s)
    real(wp), intent(in) :: x, emax, smax
    real(wp) :: s
    s = emax*x/(1.0_wp + emax*abs(x)/smax)
  end function hyperbola_stress

  !> Slope of hyperbola_stress: Emax/(1 + Emax |x|/smax)^2.
  pure elemental function hyperbola_tangent(x, emax, smax) result(t)
    real(wp), intent(in) :: x, emax, smax
    real(wp) :: t
    t = emax/(1.0_wp + emax*abs(x)/smax)**2
  end function hyperbola_tangent

  !> Skeleton stress: smax_pos for tension (e > 0), smax_neg (> 0) for compression.
  pure elemental function skeleton_stress(e, emax, smax_pos, smax_neg) result(s)
    real(wp), intent(in) :: e, emax, smax_pos, smax_neg
    real(wp) :: s
    s = hyperbola_stress(e, emax, merge(smax_pos, smax_neg, e >= 0.0_wp))
  end function skeleton_stress

  !> Tangent of the skeleton, ds/de.
  pure elemental function skeleton_tangent(e, emax, smax_pos, smax_neg) result(t)
    real(wp), intent(in) :: e, emax, smax_pos, smax_neg
    real(wp) :: t
    t = hyperbola_tangent(e, emax, merge(smax_pos, smax_neg, e >= 0.0_wp))
  end function skeleton_tangent

  !> Strength of the hyperbola of every Masing branch: the mean of the two strengths.
  pure elemental function masing_branch_strength(smax_pos, smax_neg) result(sb)
    real(wp), intent(in) :: smax_pos, smax_neg
    real(wp) :: sb
    sb = 0.5_wp*(smax_pos + smax_neg)
  end function masing_branch_strength

  !> Strain where the branch from skeleton point e1 rejoins the skeleton of the other sign.
  pure elemental function masing_mirror_strain(e1, smax_pos, smax_neg) result(em)
    real(wp), intent(in) :: e1, smax_pos, smax_neg
    real(wp) :: em
    ! same fraction of the reference strain smax/Emax on the other side
    if (e1 >= 0.0_wp) then
      em = -e1*(smax_neg/smax_pos)
    else
      em = -e1*(smax_pos/smax_neg)
    end if
  end function masing_mirror_strain

  !> Follows one spring from its committed state to the trial strain e along a monotone path:
  !> the level reached (stack count after a commit), whether the committed point is pushed as
  !> a reversal, and the stress and tangent at e. Changes nothing.
  pure subroutine masing_walk(e, emax, smax_pos, smax_neg, e_c, s_c, dir, count, e_rev, &
      s_rev, level, push, s, t)
    real(wp), intent(in) :: e, emax, smax_pos, smax_neg, e_c, s_c
    integer(ip), intent(in) :: dir, count
    real(wp), intent(in) :: e_rev(:), s_rev(:)
    integer(ip), intent(out) :: level
    logical, intent(out) :: push
    real(wp), intent(out) :: s, t
    integer(ip) :: m, d
    real(wp) :: e0, s0, e_aim, sb

    sb = masing_branch_strength(smax_pos, smax_neg)
    m = 0
    if (e > e_c) m = 1
    if (e < e_c) m = -1
    ! a reversal is recorded only while the stack has room; past depth D the innermost
    ! branch is retraced (see docs/nonlinear.md, overflow)
    push = dir /= 0 .and. m == -dir .and. count < size(e_rev)
    level = count
    if (push) level = count + 1
    if (m /= 0) then
      do while (level > 0)
        call level_params(level, e0, s0, d, e_aim)
        if (m == d) then
          ! forward: at or past its aim the branch has rejoined the curve it interrupted
          if (real(d, wp)*(e - e_aim) < 0.0_wp) exit
          level = max(level - 2_ip, 0_ip)
        else
          ! backward on the innermost branch (overflow retrace): past its start we are back
          ! on the curve that carried its reversal point, travelling forward along it
          if (real(d, wp)*(e - e0) > 0.0_wp) exit
          level = level - 1_ip
        end if
      end do
    end if
    if (level == 0) then
      s = skeleton_stress(e, emax, smax_pos, smax_neg)
      t = skeleton_tangent(e, emax, smax_pos, smax_neg)
    else if (m == 0 .and. level == count) then
      call level_params(level, e0, s0, d, e_aim)
      s = s_c
      t = hyperbola_tangent(0.5_wp*(e - e0), emax, sb)
    else
      call level_params(level, e0, s0, d, e_aim)
      s = s0 + 2.0_wp*hyperbola_stress(0.5_wp*(e - e0), emax, sb)
      t = hyperbola_tangent(0.5_wp*(e - e0), emax, sb)
    end if
    if (level == 0 .and. m == 0) s = s_c

  contains

    !> Start point, direction and aim strain of branch level k (k = count+1: the pushed one).
    pure subroutine level_params(k, e0, s0, d, e_aim)
      integer(ip), intent(in) :: k
      real(wp), intent(out) :: e0, s0, e_aim
      integer(ip), intent(out) :: d
      if (push .and. k == count + 1) then
        e0 = e_c
        s0 = s_c
      else
        e0 = e_rev(k)
        s0 = s_rev(k)
      end if
      if (k >= 2) then
        e_aim = e_rev(k - 1)
        d = merge(1_ip, -1_ip, e_aim > e0)
      else
        ! R_1 lies on the skeleton and its branch heads for the other side
        e_aim = masing_mirror_strain(e0, smax_pos, smax_neg)
        d = merge(-1_ip, 1_ip, e0 > 0.0_wp)
      end if
    end subroutine level_params
  end subroutine masing_walk

  !> Stress and tangent of one spring at the trial strain e, reached monotonically from the
  !> committed state (e_c, s_c, dir, count, e_rev, s_rev); the state is not changed.
  pure subroutine masing_trial(e, emax, smax_pos, smax_neg, e_c, s_c, dir, count, e_rev, &
      s_rev, s, t)
    real(wp), intent(in) :: e, emax, smax_pos, smax_neg, e_c, s_c
    integer(ip), intent(in) :: dir, count
    real(wp), intent(in) :: e_rev(:), s_rev(:)
    real(wp), intent(out) :: s, t
    integer(ip) :: level
    logical :: push
    call masing_walk(e, emax, smax_pos, smax_neg, e_c, s_c, dir, count, e_rev, s_rev, &
                     level, push, s, t)
  end subroutine masing_trial

  !> Moves one spring's committed state to strain e: records a reversal at the committed point
  !> when the strain turns back, closes the loops and branches passed on the way to e.
  pure subroutine masing_commit(e, emax, smax_pos, smax_neg, e_c, s_c, dir, count, e_rev, &
      s_rev, e_max_pos, e_max_neg)
    real(wp), intent(in) :: e, emax, smax_pos, smax_neg
    real(wp), intent(inout) :: e_c, s_c
    integer(ip), intent(inout) :: dir, count
    real(wp), intent(inout) :: e_rev(:), s_rev(:)
    real(wp), intent(inout) :: e_max_pos, e_max_neg
    integer(ip) :: level
    logical :: push
    real(wp) :: s, t
    if (e == e_c) return
    call masing_walk(e, emax, smax_pos, smax_neg, e_c, s_c, dir, count, e_rev, s_rev, &
                     level, push, s, t)
    if (push .and. level == count + 1) then
      e_rev(level) = e_c
      s_rev(level) = s_c
    end if
    count = level
    dir = merge(1_ip, -1_ip, e > e_c)
    e_c = e
    s_c = s
    e_max_pos = max(e_max_pos, e)
    e_max_neg = min(e_max_neg, e)
  end subroutine masing_commit

  !> The constants of the law of a spring of strengths smax_pos, smax_neg (with
  !> Emax = 1): the strengths, the branch strength and the mirror factors of a tension and of
  !> a compression point, each computed as masing_branch_strength, masing_mirror_strain do.
  pure function masing_constants(smax_pos, smax_neg) result(p)
    real(wp), intent(in) :: smax_pos, smax_neg
    real(wp) :: p(n_masing_constants)
    p(k_pos) = smax_pos
    p(k_neg) = smax_neg
    p(k_branch) = masing_branch_strength(smax_pos, smax_neg)
    p(k_mirror_pos) = smax_neg/smax_pos
    p(k_mirror_neg) = smax_pos/smax_neg
  end function masing_constants

  !> The curves of one spring in its committed state (strain e_c, direction dir, stack count
  !> and reversal points e_rev, s_rev of depth size(e_rev); mirror factors mp = smax_neg /
  !> smax_pos, mn = smax_pos / smax_neg), that masing_walk would follow from it: a move to a
  !> strain e in the open interval (lo, hi) ends on the curve it starts on (e /= e_c; lo is
  !> e_c or -huge when no move down does, hi likewise); a move in direction ps (+1, -1; 0:
  !> none) pushes e_c as a reversal and starts a branch there, any other move continues on
  !> the current curve: the skeleton (e0 = s0 = 0, hk = 1) or the branch from (e0, s0)
  !> (hk = 1/2). docs/nonlinear.md, section 6a.
  pure subroutine masing_curve(e_c, dir, count, e_rev, s_rev, mp, mn, lo, hi, e0, s0, hk, ps)
    real(wp), intent(in) :: e_c, e_rev(:), s_rev(:), mp, mn
    integer(ip), intent(in) :: dir, count
    real(wp), intent(out) :: lo, hi, e0, s0, hk, ps
    integer :: side
    real(wp) :: bound
    if (count == 0) then
      e0 = 0.0_wp
      s0 = 0.0_wp
      hk = 1.0_wp
    else
      e0 = e_rev(count)
      s0 = s_rev(count)
      hk = 0.5_wp
    end if
    ps = 0.0_wp
    if (dir /= 0 .and. count < size(e_rev)) ps = real(-dir, wp)
    lo = e_c
    hi = e_c
    do side = -1, 1, 2
      if (real(side, wp) == ps) then
        ! the branch the push starts, from the committed point
        bound = branch_end(count + 1_ip, e_c, side)
      else if (count == 0) then
        bound = real(side, wp)*huge(1.0_wp)
      else
        bound = branch_end(count, e0, side)
      end if
      if (side > 0) then
        hi = bound
      else
        lo = bound
      end if
    end do

  contains

    !> Where branch k, starting at strain start, ends for a move in direction side: its aim
    !> (masing_walk's level_params) when the move goes its way, else its start.
    pure real(wp) function branch_end(k, start, side) result(b)
      integer(ip), intent(in) :: k
      real(wp), intent(in) :: start
      integer, intent(in) :: side
      real(wp) :: aim
      integer :: d
      if (k >= 2) then
        aim = e_rev(k - 1)
        d = merge(1, -1, aim > start)
      else
        aim = -start*merge(mp, mn, start >= 0.0_wp)
        d = merge(-1, 1, start > 0.0_wp)
      end if
      b = merge(aim, start, side == d)
    end function branch_end
  end subroutine masing_curve

  !> Allocates the state of n_springs virgin springs (at zero strain) with stack depth D
  !> (default masing_default_depth); stat = 1 for n_springs < 0 or depth < 1.
  subroutine masing_state_init(this, n_springs, depth, stat)
    class(masing_state_t), intent(inout) :: this
    integer(ip), intent(in) :: n_springs
    integer(ip), intent(in), optional :: depth
    integer(ip), intent(out), optional :: stat
    integer(ip) :: d
    integer :: ierr
    call this%free()
    d = masing_default_depth
    if (present(depth)) d = depth
    if (n_springs < 0 .or. d < 1) then
      if (present(stat)) then
        stat = 1
        return
      end if
      error stop 'masing_state_init: n_springs must be >= 0 and depth >= 1'
    end if
    if (present(stat)) stat = 0
    this%n = n_springs
    this%depth = d
    allocate(this%strain(n_springs), this%stress(n_springs), this%dir(n_springs), &
             this%count(n_springs), this%e_rev(d, n_springs), this%s_rev(d, n_springs), &
             this%e_max_pos(n_springs), this%e_max_neg(n_springs), stat=ierr)
    if (ierr /= 0) then
      ! out of memory: the caller that asked for a status reports it
      if (present(stat)) then
        stat = 2_ip
        return
      end if
      error stop 'masing_state_init: out of memory'
    end if
    this%strain = 0.0_wp
    this%stress = 0.0_wp
    this%dir = 0
    this%count = 0
    this%e_rev = 0.0_wp
    this%s_rev = 0.0_wp
    this%e_max_pos = 0.0_wp
    this%e_max_neg = 0.0_wp
  end subroutine masing_state_init

  !> Releases the arrays.
  subroutine masing_state_free(this)
    class(masing_state_t), intent(inout) :: this
    if (allocated(this%strain)) deallocate(this%strain)
    if (allocated(this%stress)) deallocate(this%stress)
    if (allocated(this%dir)) deallocate(this%dir)
    if (allocated(this%count)) deallocate(this%count)
    if (allocated(this%e_rev)) deallocate(this%e_rev)
    if (allocated(this%s_rev)) deallocate(this%s_rev)
    if (allocated(this%e_max_pos)) deallocate(this%e_max_pos)
    if (allocated(this%e_max_neg)) deallocate(this%e_max_neg)
    this%n = 0
    this%depth = 0
  end subroutine masing_state_free

  !> Trial stress and tangent of spring i at strain e; the state is not changed.
  pure subroutine masing_state_trial(this, i, e, emax, smax_pos, smax_neg, s, t)
    class(masing_state_t), intent(in) :: this
    integer(ip), intent(in) :: i
    real(wp), intent(in) :: e, emax, smax_pos, smax_neg
    real(wp), intent(out) :: s, t
    call masing_trial(e, emax, smax_pos, smax_neg, this%strain(i), this%stress(i), &
                      this%dir(i), this%count(i), this%e_rev(:, i), this%s_rev(:, i), s, t)
  end subroutine masing_state_trial

  !> Commits spring i to strain e.
  pure subroutine masing_state_commit(this, i, e, emax, smax_pos, smax_neg)
    class(masing_state_t), intent(inout) :: this
    integer(ip), intent(in) :: i
    real(wp), intent(in) :: e, emax, smax_pos, smax_neg
    call masing_commit(e, emax, smax_pos, smax_neg, this%strain(i), this%stress(i), &
                       this%dir(i), this%count(i), this%e_rev(:, i), this%s_rev(:, i), &
                       this%e_max_pos(i), this%e_max_neg(i))
  end subroutine masing_state_commit

  !> Trial stresses and tangents of all springs at strains e(:); the state is not changed.
  pure subroutine masing_stress_all(state, e, emax, smax_pos, smax_neg, s, t)
    type(masing_state_t), intent(in) :: state
    real(wp), intent(in) :: e(:), emax(:), smax_pos(:), smax_neg(:)
    real(wp), intent(out) :: s(:), t(:)
    integer(ip) :: i
    do i = 1, state%n
      call masing_trial(e(i), emax(i), smax_pos(i), smax_neg(i), state%strain(i), &
                        state%stress(i), state%dir(i), state%count(i), state%e_rev(:, i), &
                        state%s_rev(:, i), s(i), t(i))
    end do
  end subroutine masing_stress_all

  !> Commits all springs to strains e(:).
  pure subroutine masing_commit_all(state, e, emax, smax_pos, smax_neg)
    type(masing_state_t), intent(inout) :: state
    real(wp), intent(in) :: e(:), emax(:), smax_pos(:), smax_neg(:)
    integer(ip) :: i
    do i = 1, state%n
      call masing_commit(e(i), emax(i), smax_pos(i), smax_neg(i), state%strain(i), &
                         state%stress(i), state%dir(i), state%count(i), state%e_rev(:, i), &
                         state%s_rev(:, i), state%e_max_pos(i), state%e_max_neg(i))
    end do
  end subroutine masing_commit_all
end module iem_masing
