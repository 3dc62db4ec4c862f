!> Cost of exact summation (src/parallel/iem_exact_sum.f90) per term against a plain sum, on
!> one rank. Build and run (a Release build; the target is not part of 'all'):
!>
!>     cmake --build build --target bench_exact_sum && build/tests/bench_exact_sum
!>
!> Terms are energies-like (positive, a few decades of magnitude) and, second, of mixed signs
!> over 120 binary orders; each array is summed repeatedly (best of several timings) in L1-
!> and L2-sized arrays and in one that lives in memory; add_scaled(x, w) is timed against
!> add(w*x(i)) term by term. Times are CPU time of the process
!> (cpu_time), which a machine shared with other jobs disturbs less than wall time.
program exact_sum_cost
  use mpi_f08, only: MPI_Init, MPI_Finalize, MPI_COMM_WORLD
  use iem_kinds, only: wp, i8
  use iem_exact_sum, only: exact_sum_t
  implicit none
  integer, parameter :: sizes(3) = [2000, 100000, 4000000]
  integer :: is, kind_of_terms
  real(wp), allocatable :: x(:)
  real(wp) :: u(2)
  integer :: i

  call MPI_Init()
  write(*, '(a)') 'exact summation: CPU ns per term (best of 5), one rank; allreduce: ns per call'
  write(*, '(a8, 1x, a7, 6(1x, a12))') 'terms', 'kind', 'plain sum', 'add_array', &
    'add (scalar)', 'add_scaled', 'add(w*x(i))', 'allreduce'
  do kind_of_terms = 1, 2
    do is = 1, size(sizes)
      allocate(x(sizes(is)))
      do i = 1, size(x)
        call random_number(u)
        if (kind_of_terms == 1) then
          x(i) = 0.5_wp*(1.0_wp + u(1))*10.0_wp**(6.0_wp*u(2) - 3.0_wp)
        else
          x(i) = scale(2.0_wp*u(1) - 1.0_wp, int(120.0_wp*u(2)) - 60)
        end if
      end do
      call measure(x, merge('energy ', 'mixed  ', kind_of_terms == 1))
      deallocate(x)
    end do
  end do
  call MPI_Finalize()

contains

  subroutine measure(x, label)
    real(wp), intent(in) :: x(:)
    character(len=*), intent(in) :: label
    type(exact_sum_t) :: acc
    real(wp) :: t_plain, t_array, t_scalar, t_scaled, t_products, t_reduce, t0, t1, s, s_plain
    real(wp) :: check
    integer :: rep, n_rep, r, i
    n_rep = max(1, 20000000/size(x))
    t_plain = huge(1.0_wp)
    t_array = huge(1.0_wp)
    t_scalar = huge(1.0_wp)
    t_scaled = huge(1.0_wp)
    t_products = huge(1.0_wp)
    t_reduce = huge(1.0_wp)
    check = 0.0_wp
    do r = 1, 5
      ! plain sum, in order (what the compiler does without -ffast-math)
      call cpu_time(t0)
      do rep = 1, n_rep
        s_plain = 0.0_wp
        do i = 1, size(x)
          s_plain = s_plain + x(i)
        end do
        check = check + s_plain
      end do
      call cpu_time(t1)
      t_plain = min(t_plain, (t1 - t0)/(real(n_rep, wp)*size(x)))
      call cpu_time(t0)
      do rep = 1, n_rep
        call acc%reset()
        call acc%add_array(x)
        check = check + acc%value()
      end do
      call cpu_time(t1)
      t_array = min(t_array, (t1 - t0)/(real(n_rep, wp)*size(x)))
      call cpu_time(t0)
      do rep = 1, n_rep
        call acc%reset()
        do i = 1, size(x)
          call acc%add(x(i))
        end do
        check = check + acc%value()
      end do
      call cpu_time(t1)
      t_scalar = min(t_scalar, (t1 - t0)/(real(n_rep, wp)*size(x)))
      ! the products w*x(i) added (as the damping work of a step takes its powers)
      call cpu_time(t0)
      do rep = 1, n_rep
        call acc%reset()
        call acc%add_scaled(x, 0.1_wp)
        check = check + acc%value()
      end do
      call cpu_time(t1)
      t_scaled = min(t_scaled, (t1 - t0)/(real(n_rep, wp)*size(x)))
      call cpu_time(t0)
      do rep = 1, n_rep
        call acc%reset()
        do i = 1, size(x)
          call acc%add(0.1_wp*x(i))
        end do
        check = check + acc%value()
      end do
      call cpu_time(t1)
      t_products = min(t_products, (t1 - t0)/(real(n_rep, wp)*size(x)))
      ! one allreduce and value() per call, as for a history sample (ns per call)
      call cpu_time(t0)
      do rep = 1, 1000
        call acc%allreduce(MPI_COMM_WORLD)
        s = acc%value()
      end do
      call cpu_time(t1)
      t_reduce = min(t_reduce, (t1 - t0)/1000.0_wp)
    end do
    write(*, '(i8, 1x, a7, 5(1x, f12.2), 1x, f9.0, a3)') size(x), label, 1.0e9_wp*t_plain, &
      1.0e9_wp*t_array, 1.0e9_wp*t_scalar, 1.0e9_wp*t_scaled, 1.0e9_wp*t_products, &
      1.0e9_wp*t_reduce, ' ns'
    ! keep the sums alive
    if (check == 1.0_wp .and. s == 2.0_wp) write(*, *) check
  end subroutine measure
end program exact_sum_cost
