!> The static run (analysis = 'static'): load step by load step, each relaxed to
!> equilibrium, then recorded. The sibling of the dynamic time loop: relaxation_t's step
!> takes the place of the integrator (docs/architecture.md, "Run driver and integrators").
submodule (iem_simulation) iem_simulation_static
  use iem_relaxation, only: relax_result_t
  use iem_build_info, only: iem_version
  implicit none

contains

  !> Documented at its interface in iem_simulation.f90.
  module procedure run_static
    type(relax_result_t) :: res
    integer(i8) :: k, total_iterations
    integer :: b, stat2
    real(wp) :: t, t_prev, wall0, wall_step
    logical :: diverged
    character(len=200) :: line

    associate(s => this%cfg%static)
      call log_info('iem '//iem_version//': '//itoa(this%body%n_nodes)//' nodes, '// &
        itoa(this%body%n_cells)//' cells ('//itoa(this%grid%nx)//' x '//itoa(this%grid%ny)// &
        '), '//itoa(this%n_ranks)//' ranks')
      call log_info('static analysis by dynamic relaxation: '//itoa(s%load_steps)// &
        ' load steps to t = '//rtoa(this%cfg%run%t_end)//', '//trim(s%method)// &
        ' damping, '//trim(s%mass)//' masses, tolerance '//rtoa(s%tolerance)// &
        ' (relative residual), at most '//itoa(s%max_iterations)//' iterations a step')
    end associate
    stat = 0
    msg = ''
    wall0 = MPI_Wtime()
    this%w_ext = 0.0_wp
    this%w_damp = 0.0_wp
    total_iterations = 0
    t_prev = 0.0_wp
    do k = 0, this%n_steps
      t = this%cfg%run%t_end*real(k, wp)/real(this%n_steps, wp)
      wall_step = MPI_Wtime()
      call this%relax%step(this%model, this%lat, this%halo, this%st%y, t_prev, t, res)
      total_iterations = total_iterations + res%iterations
      if (.not. (res%finite .and. res%converged)) then
        stat = 3
        if (.not. res%finite) then
          msg = 'static load step '//itoa(k)//'/'//itoa(this%n_steps)//' (t = '//rtoa(t)// &
                ') diverged (non-finite forces) after '//itoa(res%iterations)//' iterations'
        else
          msg = 'static load step '//itoa(k)//'/'//itoa(this%n_steps)//' (t = '//rtoa(t)// &
                ', load factor '//rtoa(res%load_factor)//') did not converge in '// &
                itoa(res%iterations)//' iterations: relative residual '// &
                rtoa(res%residual)//' > tolerance '//rtoa(this%cfg%static%tolerance)// &
                '; raise &static max_iterations, use more load_steps or a looser tolerance'
        end if
        call flush_history(this, stat2)
        return
      end if
      ! nonlinear springs have committed their history at the converged state (relax%step)
      this%w_ext = this%w_ext + res%work
      call record_sample(this, k, t, diverged)
      if (diverged) then
        stat = 3
        msg = 'static load step '//itoa(k)//'/'//itoa(this%n_steps)//' (t = '//rtoa(t)// &
              ') gave non-finite energies'
        call flush_history(this, stat2)
        return
      end if
      b = this%n_buf
      this%h_load(b) = res%load_factor
      this%h_iter(b) = res%iterations
      this%h_res(b) = res%residual
      call flush_history(this, stat)
      if (stat == 0) call write_frame(this, k, t, stat)
      if (stat /= 0) then
        msg = 'writing output to '//trim(this%cfg%run%output_file)//' failed'
        return
      end if
      write(line, '(a,i0,a,i0,a,f8.5,a,i8,a,es9.2,a,f9.2,a)') 'load step ', k, '/', &
        this%n_steps, '  load factor ', res%load_factor, '  iterations ', res%iterations, &
        '  residual ', res%residual, '  wall ', MPI_Wtime() - wall_step, ' s'
      call log_info(trim(line))
      t_prev = t
    end do
    call log_info('done: '//itoa(this%n_steps)//' load steps, '//itoa(total_iterations)// &
                  ' iterations in '//rtoa(MPI_Wtime() - wall0)//' s wall; energy-balance '// &
                  'error '//rtoa(this%last_balance))
  end procedure run_static

end submodule iem_simulation_static
