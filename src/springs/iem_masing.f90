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
  public :: masing_constants, masing_springs, n_masing_constants

  !> Default number of reversal points kept per spring (nested loops remembered: depth/2).
  integer(ip), parameter :: masing_default_depth = 8

  !> Number of constants per spring that masing_springs reads (masing_constants): the two
  !> strengths, the branch strength and the two mirror factors.
  integer, parameter :: n_masing_constants = 5
  integer, parameter :: k_pos = 1, k_neg = 2, k_branch = 3, k_mirror_pos = 4, k_mirror_neg = 5
  !> Springs per block of masing_springs (its work arrays stay in L1 cache).
  integer, parameter :: block = 128

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

  !> The constants masing_springs reads for a spring of strengths smax_pos, smax_neg (with
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

  !> Stresses s of n springs with Emax = 1 (constants p(i, :) from masing_constants) at the
  !> strains e, each reached monotonically from its committed state (e_c .. e_max_neg, stack
  !> depth D), and that state's strain and stress e_was, s_was; with accept, the state moved
  !> to e. Bit for bit masing_trial / masing_commit of each spring: the springs whose move
  !> ends on the curve it starts on (their current one, or the branch a reversal starts) are
  !> evaluated and committed in branch-free loops over a block of springs, the others (a
  !> branch reaches its aim, an overflow retrace its start) take the scalar state machine.
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
    integer :: b, nb, k, i
    integer(ip) :: lev, m, n0, d0, push, fast, short
    logical :: moved
    real(wp) :: t, e0, s0, aim, d, x, r, y, ek, ec, sc, et, st, eb, pp, pn, pb, mp, mn
    real(wp) :: mirror, half, on_branch
    do b = 0, n - 1, block
      nb = min(block, n - b)
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
      ! the other springs take the state machine
      do k = 1, nb
        if (todo(k) /= 2) cycle
        i = b + k
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
