!> Cost of the nonlinear springs' commit every step (iem_masing_fast's masing_springs, what
!> velocity Verlet runs for every spring each step) per spring and step, away from the rest of
!> a run: the AVX2 C block (iem_masing_simd.c) where it is built, and the Fortran loops. Build
!> and run (a Release build; the target is not part of 'all'):
!>
!>     cmake --build build --target bench_masing_block && build/tests/bench_masing_block
!>
!> Springs of three strength pairs (as test_iem_masing) with stacks of depth 8 follow their
!> own slow oscillation past their reference strains, plus a jitter of `jitter` reference
!> strains a step (uniform, deterministic) that turns them back now and then; each line gives
!> the share of the moves that push a reversal and of those that leave a level (a loop that
!> closes, a retrace), to compare with a scene's (docs/benchmarks.md gives those of the
!> 729-node nonlinear cantilever with velocity Verlet). The springs are committed in calls of
!> 768 (a chunk of 64 cells), as the kernel does. Times are CPU time of the process
!> (cpu_time) around the calls only, the best of 3 runs from a fresh state.
program masing_block_cost
  use iem_kinds, only: wp, ip
  use iem_masing, only: masing_state_t, masing_constants, n_masing_constants
  use iem_masing_fast, only: masing_springs
  use iem_masing_simd, only: use_masing_simd, masing_simd
  implicit none
  integer, parameter :: call_size = 768, depth = 8, n_rep = 3
  integer, parameter :: n_springs = 7680, n_steps = 2000
  real(wp), parameter :: jitters(3) = [0.0_wp, 0.06_wp, 0.3_wp]
  integer :: ij, ip_

  write(*, '(a)') 'masing_springs with commit: CPU ns per spring and step (best of 3); '// &
    'moves that push a reversal, that leave a level'
  write(*, '(a7, 1x, a6, 1x, a7, 2(1x, a9), 1x, a8)') 'springs', 'jitter', 'path', &
    'ns', 'pushed', 'left'
  do ij = 1, size(jitters)
    do ip_ = 1, 2
      if (ip_ == 1) then
        use_masing_simd = .true.
        if (.not. masing_simd()) cycle
      else
        use_masing_simd = .false.
      end if
      call measure(n_springs, n_steps, jitters(ij), merge('C AVX2 ', 'Fortran', ip_ == 1))
    end do
  end do
  use_masing_simd = .true.

contains

  !> Run n springs for steps steps n_rep times; print the best time and the moves' shares.
  subroutine measure(n, steps, jitter, label)
    integer, intent(in) :: n, steps
    real(wp), intent(in) :: jitter
    character(len=*), intent(in) :: label
    type(masing_state_t) :: st
    real(wp) :: e(n), p(n, n_masing_constants), er(n), amp(n), omega(n), phase(n)
    real(wp) :: s(n), e_was(n), s_was(n), t0, t1, best, time
    integer(ip) :: count_was(n)
    integer(kind=8) :: seed, n_moved, n_pushed, n_left
    integer :: rep, step, i, b, nb
    best = huge(1.0_wp)
    do rep = 1, n_rep
      seed = 12345
      call st%init(int(n, ip), int(depth, ip))
      do i = 1, n
        select case (mod(i, 3))
        case (0)
          p(i, :) = masing_constants(1.0e-4_wp, 1.0e-4_wp)
        case (1)
          p(i, :) = masing_constants(1.0e-4_wp, 1.0e-3_wp)
        case default
          p(i, :) = masing_constants(1.0e-3_wp, 1.0e-4_wp)
        end select
        er(i) = 1.0e-4_wp
        amp(i) = 1.0_wp + 3.0_wp*uniform(seed)
        omega(i) = 8.0_wp*atan(1.0_wp)/(100.0_wp + 300.0_wp*uniform(seed))
        phase(i) = 8.0_wp*atan(1.0_wp)*uniform(seed)
      end do
      time = 0.0_wp
      n_moved = 0
      n_pushed = 0
      n_left = 0
      do step = 1, steps
        do i = 1, n
          e(i) = er(i)*(amp(i)*sin(omega(i)*step + phase(i)) + jitter*(uniform(seed) - 0.5_wp))
        end do
        count_was = st%count
        call cpu_time(t0)
        do b = 0, n - 1, call_size
          nb = min(call_size, n - b)
          call masing_springs(nb, depth, e(b + 1:b + nb), p(b + 1:b + nb, :), .true., &
                              st%strain(b + 1:b + nb), st%stress(b + 1:b + nb), &
                              st%dir(b + 1:b + nb), st%count(b + 1:b + nb), &
                              st%e_rev(:, b + 1:b + nb), st%s_rev(:, b + 1:b + nb), &
                              st%e_max_pos(b + 1:b + nb), st%e_max_neg(b + 1:b + nb), &
                              s(b + 1:b + nb), e_was(b + 1:b + nb), s_was(b + 1:b + nb))
        end do
        call cpu_time(t1)
        time = time + (t1 - t0)
        n_moved = n_moved + count(e /= e_was)
        n_pushed = n_pushed + count(st%count > count_was)
        n_left = n_left + count(st%count < count_was)
      end do
      best = min(best, time)
      call st%free()
    end do
    write(*, '(i7, 1x, f6.2, 1x, a7, 1x, f9.2, 2(1x, f8.1, "%"))') n, jitter, label, &
      1.0e9_wp*best/(real(n, wp)*steps), 100.0_wp*real(n_pushed, wp)/max(1_8, n_moved), &
      100.0_wp*real(n_left, wp)/max(1_8, n_moved)
  end subroutine measure

  !> Uniform numbers in [0, 1) from a 64-bit xorshift sequence (deterministic).
  real(wp) function uniform(seed)
    integer(kind=8), intent(inout) :: seed
    seed = ieor(seed, ishft(seed, 13))
    seed = ieor(seed, ishft(seed, -7))
    seed = ieor(seed, ishft(seed, 17))
    uniform = real(ishft(seed, -11), wp)/real(2_8**53, wp)
  end function uniform
end program masing_block_cost
